# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py); the zone's
# methods that take a train's state take it as a TrainState, so they read its slots directly; a report is a dict; the
# parts it holds are their C types, so their methods are called directly

cimport cython

from cbtc.zone.commanding cimport CommandWriter
from cbtc.zone.estimators cimport Estimators
from cbtc.zone.fast_reports cimport FastReports
from cbtc.zone.indexes cimport ReportAges, TrainOrder
from cbtc.zone.situations cimport Departures
from cbtc.zone.stations cimport StationStops
from cbtc.zone.train_state cimport TrainState

cdef class ZoneController:
    cdef dict __dict__
    cdef object __weakref__
    cdef public TrainOrder order
    cdef public ReportAges ages
    cdef public Departures departures
    cdef public FastReports fast
    cdef public Estimators estimators
    cdef public StationStops stops
    cdef public CommandWriter writer
    cdef public object _unanswered
    cdef public object layout, client, now_fn, policy, params, cycle_s
    cdef public object event_driven, zone_id, _rng, session_id, trains
    cdef public object unknown_reports, invalid_reports, refusals, key_source, cycles, ranging_sigma_m
    cdef public object use_measured_gap, commands, reports, views, obstacles, watch, swept
    cdef public object network

    @cython.locals(report=dict, previous=dict)
    cpdef _take_report(self, TrainState state, payload, recv_s)
    cpdef _decoded(self, TrainState state, payload, recv_s)
    cpdef _position_m(self, TrainState state)
    cpdef _update(self, TrainState state, leader, all_located, now_s)
    cpdef _authorise(self, TrainState state, leader, all_located, now_s)
    cpdef _took(self, TrainState state, auth)
    cpdef _answer(self, TrainState state, now_s)
    cpdef _command(self, TrainState state, safe_m, stop_m, v_cap_mps, acc_mps2, dec_mps2, now_s)
