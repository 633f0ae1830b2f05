# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py); the
# envelope's arithmetic on C doubles, where the same float operations run in the same order
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

cimport cython

@cython.locals(rate=cython.double, v_knee=cython.double, t_knee=cython.double)
cpdef double ride_mps(double v0_mps, double dt_s, double v_ss_mps, double tau_s, double up_mps2, double down_mps2)

cdef class SpeedEnvelope:
    cdef object __weakref__
    cdef public object profile, motor_tol, window_s, _anchors, _last, _gain
    cdef public object _gain_tol

    @cython.locals(dt_s=cython.double, v0=cython.double, excess=cython.double, fall_mps=cython.double,
                   rise_mps=cython.double, anchor=list, low=tuple, high=tuple)
    cpdef observe(self, double t_s, double v_mps, duty_pct)
