# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class SpeedEnvelope:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object profile, motor_tol, window_s, _anchors, _last, _gain
    cdef public object _gain_tol

