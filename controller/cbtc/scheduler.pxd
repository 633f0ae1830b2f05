# For the compiled build (setup.py) alone: these classes as C types whose attributes set in their methods live in
# slots, so that self.x is a field read, not a dict lookup; any other attribute still goes to the instance __dict__.
# tests/test_compiled_build.py holds the build to the source, bit for bit.

cdef class VirtualScheduler:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object _now_s, _queue, _counter, _stopped

cdef class _Periodic:
    cdef dict __dict__
    cdef object __weakref__
    cdef public object _scheduler, _period_s, _fn, _k, _start_s, _handle

