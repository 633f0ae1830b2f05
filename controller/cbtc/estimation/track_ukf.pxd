# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py); the
# filter's arithmetic on C doubles, where the same float operations run in the same order
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

cimport cython

@cython.locals(a=cython.double, u00=cython.double, u01=cython.double, u02=cython.double, u03=cython.double,
               u11=cython.double, u12=cython.double, u13=cython.double, u22=cython.double, u23=cython.double,
               p00=cython.double, p01=cython.double, p02=cython.double, p03=cython.double, p11=cython.double,
               p12=cython.double, p13=cython.double, p22=cython.double, p23=cython.double, p33=cython.double)
cpdef list _cholesky_upper4(P, double scale)

cdef class TrackUkf:
    cdef object __weakref__
    cdef public object layout, noise, mean, cov, t_s, _spread
    cdef public object _wm0, _wc0, _w, _loop_m, _closed, _gate1
    cdef public object _gate2

    @cython.locals(dt_s=cython.double, v=cython.double, k=cython.double, c=cython.double, spread=cython.double,
                   pss=cython.double, psv=cython.double, psd=cython.double, pvv=cython.double, pvd=cython.double,
                   pdd=cython.double, psk=cython.double, pvk=cython.double, pdk=cython.double, pkk=cython.double,
                   ab0=cython.double, ab1=cython.double, gain=cython.double, a=cython.double, b=cython.double,
                   q=cython.double, adt=cython.double, q3=cython.double, q2=cython.double, q1=cython.double,
                   travel_m=cython.double, dv=cython.double, ss=cython.double, sv=cython.double, sd=cython.double,
                   vv=cython.double, vd=cython.double, dd=cython.double, sk_=cython.double, dk_=cython.double,
                   kk=cython.double)
    cpdef predict_to(self, t_s)

