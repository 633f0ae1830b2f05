# The compiled build's C types for these classes: their attributes in slots (setup.py, tests/test_pxd.py)

cdef class VirtualTrain:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object train_id, layout, profile, client, s0_m, length_m, tail_car, travelled_m
    cdef public object v_mps, a_mps2, clock_offset_ms, encoder, ips, rfid, train_line
    cdef public object motor, _key, _config, _ranging, boots, obu
    cdef public object _last_s, _now_s, frozen, stopped_dead, _rollback_m, _rollback_mps
    cdef public object _reverse_m, _back_v_mps, route, legs, leg, cab, turns

