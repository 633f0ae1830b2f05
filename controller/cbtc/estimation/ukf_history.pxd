# The compiled build's C types for the estimator's history (setup.py, tests/test_pxd.py): their attributes in slots
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

cdef class FilterEvent:
    cdef object __weakref__
    cdef public object t_s, kind, data, sort_key

cdef class FilterState:
    cdef object __weakref__
    cdef public object snap, ips_used, ips_rejected, tags_used, tags_rejected, gated
    cdef public object relocations, consensus, innovations, disagree, disagreements, tag_offset
    cdef public object speed_steps, doubt, pending, agreeing, reach, tag_story, vouched, ips_d_m

    cpdef covered(self, s_m, sigma_s_m, ring_m)
    cpdef copy_with(self, snap)
