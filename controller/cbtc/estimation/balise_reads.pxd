# The compiled build's C type for BaliseReads (setup.py, tests/test_pxd.py): the filter is a TrackUkf, so its slots
# are read directly
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

from cbtc.estimation.track_ukf cimport TrackUkf

cdef class BaliseReads:
    cdef object __weakref__
    cdef public object layout, noise, params

    cpdef reckon(self, TrackUkf f, reach, d_m, scale_sigma0, vouched=*, ips_d_m=*)
