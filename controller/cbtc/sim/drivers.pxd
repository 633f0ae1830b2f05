# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py); the RFID
# reader's search for tags in range runs on C doubles and indices

cimport cython

cdef class SimEncoder:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object _profile, _rng, signed, distance_m, scale_fault, _since_edge_s, age_us, way, cab

cdef class SimIps:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object _profile, _layout, _rng, _z_mm, _pending, _next_sample_ms
    cdef public object last_fix_ms, crc_errors, frames_ok, unplugged, offset_m

cdef class SimRfid:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object _profile, _layout, _rng, _inside, _images, _tag_s_m
    cdef public object _tag_index, present, wrong_tag, data, _s_m

    @cython.locals(range_m=cython.double, s_m=cython.double, low_m=cython.double, high_m=cython.double,
                   shift_m=cython.double, first=cython.Py_ssize_t, end=cython.Py_ssize_t, i=cython.Py_ssize_t)
    cpdef _near(self)

cdef class SimTrainLine:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object open

cdef class SimMotor:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object mode, duty_pct

