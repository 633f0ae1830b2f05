# For the compiled build (setup.py) alone: these classes as C types whose attributes set in their methods live in
# slots, so that self.x is a field read, not a dict lookup; any other attribute still goes to the instance __dict__.
# tests/test_compiled_build.py holds the build to the source, bit for bit.

cdef class BootTracker:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object boot, last_seq, last_recv_s, answered, left, _leaving
    cdef public object _leaving_seq

