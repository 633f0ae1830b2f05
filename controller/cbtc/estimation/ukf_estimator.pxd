# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py); the
# filter's step reads its filter, its states and its events as C types

cimport cython

from cbtc.estimation.balise_reads cimport BaliseReads
from cbtc.estimation.ips_agreement cimport IpsAgreement
from cbtc.estimation.track_ukf cimport TrackUkf
from cbtc.estimation.ukf_history cimport FilterEvent, FilterState
from cbtc.estimation.wheel_watch cimport WheelWatch

cdef class UkfEstimator:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object layout, profile, params, noise, localized, balises
    cdef public object late_measurements, _clock, _events, _keys, _estimate_memo, _states
    cdef public object _base, _doubt_span, _declared, _trimmed, _filter, _filter_holds, _band0
    cdef public object _scale_sigma0
    cdef public WheelWatch _wheel
    cdef public IpsAgreement _ips
    cdef public BaliseReads _reads

    @cython.locals(f=TrackUkf, new=FilterState)
    cpdef _apply(self, FilterState state, FilterEvent event)
    cpdef _take_tag(self, TrackUkf f, FilterState state, FilterState new, tuple data)
    cpdef _take_ips(self, TrackUkf f, FilterState state, FilterState new, tuple data)

    cpdef on_report(self, dict report, board_clock)
