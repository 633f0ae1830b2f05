# The compiled build's C type for WheelWatch (setup.py, tests/test_pxd.py): the filter's state is a FilterState, so
# its slots are read directly; a report is a dict
# Its instances hold their slots only (no __dict__): a call of its methods goes straight to C, no look for an override

from cbtc.estimation.ukf_history cimport FilterState

cdef class WheelWatch:
    cdef object __weakref__
    cdef public object profile, params, odo_m, first_odo_m, t_s, top_mps, rolled_m, roll_run_m, v_mps, duty_pct
    cdef public object before, envelope, motor, speed_drifts

    cpdef take(self, dict report, t_s, FilterState state, scale_sigma0)
    cpdef _least_speed_mps(self, v_mps, FilterState state)
    cpdef _may_have_turned(self, t_s, v_mps, FilterState state)
    cpdef _surely_forward_m(self, FilterState state, scale_sigma0)
    cpdef _speed_step(self, t_s, v_mps, duty_pct)
    cpdef _step_over(self, t0_s, v0_mps, d0_pct, t_s, v_mps, duty_pct)
    cpdef _drifted(self, t_s, v_mps, duty_pct, FilterState state)
    cpdef scale_error(self, FilterState state)
    cpdef scale_low(self, FilterState state, k_sigma, scale_sigma0)
    cpdef scale_high(self, FilterState state)
    cpdef scale_settled(self, FilterState state)
    cpdef scale_open(self, FilterState state)
