# The compiled build's C type for TrainState: its attributes in slots (setup.py, tests/test_pxd.py); the zone's
# methods take a train's state as this type (controller.pxd), so they read its slots directly

cdef class TrainState:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object setup, train_id, estimator, rank, on_change, clock, frame, sensor_frame, leg, stops
    cdef public object turn_at_s
    cdef public object report, report_recv_s, report_t_s, boots, next_stop, leaving
    cdef public object dwell_until_s, odo_moved, still_since_s, dwells, limit_s, safe_m
    cdef public object limited_by, eoa_mm, travel_dir, cmd_seq, command, reports_rejected, last_reject
    cdef public object stop_overruns, restarts, answered_s, fast_until_s, fast_need_m, leader_data_t_s
    cdef public object sigma_m, authority, mode, rng_gap, gap_alarm, gap_alarms
    cdef public object deaf_since_s, encoder_failed, encoder_failures, odometer_jumps, measurements_dropped, failures
    cdef public object failures_said, reports_taken, reach_m, horizon_m, tail, track_m, doubt_span, swept_from_m, _memo
    cdef public object handed, faced
