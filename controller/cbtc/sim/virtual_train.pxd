# For the compiled build (setup.py) alone: these classes as C types whose attributes set in their methods live in
# slots, so that self.x is a field read, not a dict lookup; any other attribute still goes to the instance __dict__.
# tests/test_compiled_build.py holds the build to the source, bit for bit.

cdef class VirtualTrain:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object train_id, layout, profile, client, s0_m, travelled_m
    cdef public object v_mps, a_mps2, clock_offset_ms, encoder, ips, rfid
    cdef public object motor, _key, _config, _ranging, boots, obu
    cdef public object _last_s, _now_s, frozen, stopped_dead, _rollback_m, _rollback_mps

