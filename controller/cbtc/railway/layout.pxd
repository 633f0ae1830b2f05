# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class Layout:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object name, source, path, closed, length_m, loop_length_m
    cdef public object segment_count, stations, tags, blocks, ips, _tags_by_uid
    cdef public object _stations_by_name, wrap, is_network, graph

