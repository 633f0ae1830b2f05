# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class Simulation:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object config, scheduler, broker, zc_client, zc, policy
    cdef public object trains, strays, recorder, tail_beacons, _cycle, _keys, zone_restarts, _report_sinks
    cdef public object network, switches

