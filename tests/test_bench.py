"""`cbtc bench sim|fusion|controller|memory|startup`: each figure comes with its reference from the same run (no
timing is asserted: the figures are for people; the tests check what is measured and that ours equals the reference
where it must)."""

import json

from cbtc.cli import main


def bench(capsys, argv):
    assert main(["bench", *argv, "--json"]) == 0
    return json.loads(capsys.readouterr().out)


def test_our_filter_equals_filterpy_on_the_same_inputs(capsys):
    out = bench(capsys, ["fusion", "--trains", "3", "--steps", "12"])
    row = out["fusion"]
    assert row["max_state_difference"] < 1e-9 and row["max_covariance_difference"] < 1e-9
    assert row["ours_us"] > 0 and row["filterpy_us"] > 0 and out["machine"]["cores"] >= 1


def test_bench_sim_sets_the_run_beside_a_do_nothing_controller(capsys):
    row = bench(capsys, ["sim", "--layout", "itb_square", "--trains", "2", "--duration", "8", "--runs", "2"])["sim"][0]
    # the fastest of the runs is the figure, each run's listed beside it (the same work each: the same seed)
    assert row["runs"] == 2 and row["real_time_factor"] == max(row["real_time_factors"])
    assert row["reference_real_time_factor"] == max(row["reference_real_time_factors"])
    assert row["trains"] == 2 and row["collisions"] == 0 and row["authority_overruns"] == 0
    assert row["simulated_s"] > 7.9 and row["reference_wall_s"] > 0 and 0.0 <= row["controller_share"] < 1.0
    # the traffic: every train reports at least at the board's own 20 Hz, and each report is answered
    assert row["reports_per_train_s"] >= 19.0 and row["commands_per_report"] >= 1.0 and row["us_per_report"] > 0


def test_bench_startup_measures_each_command_beside_python(capsys):
    rows = bench(capsys, ["startup", "--runs", "1"])["startup"]
    assert rows[0]["command"] == "python -c pass" and rows[0]["vs_python"] == 1.0
    assert {r["command"] for r in rows} >= {"cbtc --help", "cbtc zone --help"}
    assert all(r["resident_mib"] > 5 for r in rows)


def test_bench_sim_wants_layout_and_trains_together(capsys):
    assert main(["bench", "sim", "--layout", "lego_oval"]) == 2
    assert "--layout and --trains together" in capsys.readouterr().err


def test_bench_controller_replays_a_run_into_a_zone_that_answers(capsys):
    row = bench(capsys, ["controller", "--trains", "3", "--duration", "5"])["controller"][0]
    assert row["trains"] == 3 and row["reports"] > 200 and row["commands"] > row["reports"] / 2
    assert row["zone_us_per_report"] > row["decode_us_per_report"] > 0


def test_bench_memory_measures_a_run_beside_one_keeping_every_sample(capsys):
    row = bench(capsys, ["memory", "--trains", "2", "--duration", "20"])["memory"]
    assert row["trains"] == 2 and row["simulated_s"] == 20.0 and row["collisions"] == 0
    assert row["end_mib"] > 5 and row["warm_mib"] > 5
    assert "reference_growth_mib_per_hour" in row and "growth_mib_per_hour" in row
