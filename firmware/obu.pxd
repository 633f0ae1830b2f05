# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py); the speed
# ring's indices are C integers

cimport cython

cdef class OnboardUnit:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object train_id, boot_id, _key, encoder, ips, rfid
    cdef public object motor, _publish, cfg, _report_topic, _cmd_topic, odo_mm
    cdef public object v_mmps, _ring_t, _ring_n, _ring_i, _last_move_ms, sid
    cdef public object cseq, cmd, cmd_expiry_ms, eoa_mm, _rejected_since_report, mode
    cdef public object v_ref_mmps, _integral, _a_lp, duty_pct, _duty_acc, _last_step_ms
    cdef public object seq, _report_slot_ms, _sent_seq, _sent_t, _ips_fix, _tags, _rfid_ms
    cdef public object faults, link_ok, _rolled
    # the defaults set in the class body (a smaller heap on the board) stay in __dict__: a C type cannot have both

    @cython.locals(i=cython.Py_ssize_t, k=cython.Py_ssize_t, j=cython.Py_ssize_t)
    cpdef _sample(self, now_ms)
