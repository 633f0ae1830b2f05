# The compiled build's C type for BaliseReads (setup.py, tests/test_pxd.py): the filter is a TrackUkf, so its slots
# are read directly

from cbtc.estimation.track_ukf cimport TrackUkf

cdef class BaliseReads:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object layout, noise, params

    cpdef reckon(self, TrackUkf f, reach, d_m, scale_sigma0)
