# The compiled build's C type for IpsAgreement (setup.py, tests/test_pxd.py): its checks are called directly at every
# IPS fix
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

cdef class IpsAgreement:
    cdef object __weakref__
    cdef public object layout, profile, params

    cpdef bias(self, innovations)
    cpdef disagreement(self, consensus, innovations)
    cpdef refutes(self, innovations, offset_m)
    cpdef consensus(self, s_m, d_m, anchors_m)
