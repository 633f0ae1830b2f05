# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py); the
# projection of a point onto the whole path runs on C doubles (the same operations in the same order)
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

cimport cython

cdef class Path:
    cdef object __weakref__
    cdef public object segments, closed, start_pose, length_m, end_pose, _starts
    cdef public object _lens, _seg, _seg_ends, _start, _len, _k
    cdef public object _arc, _safe_k, _x0, _y0, _h0, _cx
    cdef public object _cy

    @cython.locals(px=cython.double, py=cython.double, k=cython.double, x0=cython.double, y0=cython.double,
                   h0=cython.double, cx=cython.double, cy=cython.double, start=cython.double, length=cython.double,
                   d_free=cython.double, sign=cython.double, theta0=cython.double, swept=cython.double,
                   d=cython.double, qx=cython.double, qy=cython.double, d2=cython.double)
    cpdef _project_scalar(self, px, py)
