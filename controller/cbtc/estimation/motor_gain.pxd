# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class MotorGain:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object profile, motor_tol, learnt_tol, _needed, _samples, gain
    cdef public object _window, _last_t_s

