# The compiled build's C type for IpsAgreement (setup.py, tests/test_pxd.py): its checks are called directly at every
# IPS fix

cdef class IpsAgreement:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object layout, profile, params

    cpdef bias(self, innovations)
    cpdef disagreement(self, consensus, innovations)
    cpdef refutes(self, innovations, offset_m)
    cpdef consensus(self, s_m, d_m, anchors_m)
