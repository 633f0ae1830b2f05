"""`cbtc campaign`: a plan that is the same on every machine, runs judged by truth, a results file that lets a stopped
campaign finish only its missing runs, a Dask cluster giving the same table, and every violation reproduced alone by
its printed `cbtc sim` command."""

import json
import os
import shlex
import signal
import subprocess
import sys
import time

import pytest

from cbtc.cli import main
from cbtc.experiments import campaign
from cbtc.sim import faults

PATH_CLASSES = [c for c in campaign.CLASSES if campaign.runs_on(c, "itb_square")]   # the switch faults need a network
RUNS = len(PATH_CLASSES)   # one run of each class that runs on itb_square
SMALL = ["campaign", "--runs", str(RUNS), "--duration", "6", "--trains", "2", "--layouts", "itb_square"]


def figures(capsys, argv):
    status = main(argv + ["--json"])
    out = json.loads(capsys.readouterr().out)
    return status, out


def test_the_plan_is_drawn_from_the_seeds_alone_and_a_longer_campaign_extends_a_shorter_one():
    args = (campaign.CLASSES, campaign.LAYOUTS, campaign.FLEET_SIZES, 60.0, 0)
    short, long = campaign.plan(40, *args), campaign.plan(800, *args)
    assert long[:40] == short and campaign.plan(40, *args) == short
    assert {spec.fault_class for spec in long} == set(campaign.CLASSES)
    assert {(spec.layout, spec.trains) for spec in long} == {
        (lay, min(n, campaign.NETWORK_FLEET) if campaign.is_network(lay) else n)
        for lay in campaign.LAYOUTS for n in range(2, 7)}   # a network holds at most NETWORK_FLEET
    for spec in long:
        assert all(faults.parse(text) for text in spec.faults)
        if spec.fault_class == "overlapping":
            assert len(spec.faults) in (2, 3) and len({text.partition(":")[0] for text in spec.faults}) == \
                len(spec.faults)
            starts = [faults.parse(text).params["at_s"] for text in spec.faults if "at_s=" in text]
            assert max(starts) - min(starts) <= campaign.OVERLAP_S, spec.faults   # their windows overlap
        else:
            assert len(spec.faults) == {"none": 0, "combined": 2, "packed_start": 0}.get(spec.fault_class, 1)
        for text in spec.faults:
            params = faults.parse(text).params
            assert 10.0 <= params.get("at_s", 10.0) <= 30.0 + campaign.OVERLAP_S
            assert int(params.get("train", "T1")[1:]) <= spec.trains
    packed = [spec for spec in long if spec.fault_class == "packed_start"]
    assert {spec.policy for spec in packed} == {"moving_block", "fixed_block"}
    assert all(0.05 <= spec.start_gap_m <= 0.3 and f"--start-gap {spec.start_gap_m:g}" in spec.command()
               for spec in packed)
    fixed = campaign.plan(5, ["rollback:distance_m=0.3"], ["itb_square"], (3,), 60.0, 7)
    assert all(faults.parse(spec.faults[0]).params["distance_m"] == 0.3 for spec in fixed)
    assert len({faults.parse(spec.faults[0]).params["v_mps"] for spec in fixed}) == 5   # the others are drawn
    assert fixed[0].command().startswith("cbtc sim --layout itb_square --trains 3 --seed 7 --duration 60 --fault "
                                         "rollback:at_s=")


def test_bad_values_are_named_before_any_run(tmp_path, capsys):
    results = str(tmp_path / "r.jsonl")
    for extra, says in ((["--runs", "0"], "--runs: 0"), (["--trains", "2-x"], "--trains '2-x'"),
                        (["--trains", "0"], "1 train or more"), (["--layouts", "nowhere"], "nowhere"),
                        (["--duration", "4"], "--duration 4.0"), (["--fault", "nope"], "unknown"),
                        (["--fault", "stop_dead:train=T9"], "no train T9 in a run of 2 trains"),
                        (["--trains", "40"], "do not fit"), (["--workers", "0"], "--workers: 0"),
                        (["--results", str(tmp_path / "no" / "r.jsonl")], "does not exist")):
        assert main(SMALL + ["--results", results] + extra) == 2, extra
        err = capsys.readouterr().err
        assert says in err and "Traceback" not in err, (extra, err)
    assert not os.path.exists(results)


def test_a_stopped_campaign_run_again_makes_only_the_missing_runs(tmp_path, capsys):
    results = tmp_path / "r.jsonl"
    argv = ["cbtc"] + SMALL + ["--results", str(results), "--workers", "1"]
    proc = subprocess.Popen([sys.executable, "-m", "cbtc.cli"] + argv[1:], stdout=subprocess.PIPE,
                            stderr=subprocess.PIPE, text=True)
    deadline = time.monotonic() + 60
    while (not results.exists() or len(results.read_text().splitlines()) < 4) and time.monotonic() < deadline:
        time.sleep(0.05)
    proc.send_signal(signal.SIGINT)
    _out, err = proc.communicate(timeout=30)
    kept = len(results.read_text().splitlines())
    assert proc.returncode == 130 and "run the same command again" in err and 4 <= kept < RUNS
    with results.open("a") as fh:
        fh.write('{"command": "cbtc sim --lay')          # a line cut short by a kill: its run is made again
    status, first = figures(capsys, SMALL + ["--results", str(results)])
    assert first["runs"] == RUNS and first["runs_reused"] == kept and first["runs_made"] == RUNS - kept
    status_again, again = figures(capsys, SMALL + ["--results", str(results)])
    assert again["runs_made"] == 0 and again["by_fault"] == first["by_fault"] and status_again == status
    # a run made by other code (a changed estimator, say) is made again, not reused
    lines = results.read_text().splitlines()
    record = json.loads(lines[0])
    results.write_text("\n".join([json.dumps(dict(record, code="other"))] + lines[1:]) + "\n")
    assert figures(capsys, SMALL + ["--results", str(results)])[1]["runs_made"] == 1
    assert set(first["by_fault"]) == set(PATH_CLASSES) and first["by_fault"]["none"]["runs"] == 1
    for key in ("runs", "collisions", "authority_overruns", "emergency_trips", "stranded", "violations"):
        assert key in first and all(key in row for row in first["by_fault"].values() if key != "violations")
    # exit 1 exactly when a run broke the rules, and each printed command reproduces its violation alone
    assert status == (1 if first["violations"] else 0)
    for violation in first["violations"][:2]:
        argv = shlex.split(violation["command"])
        assert argv[:2] == ["cbtc", "sim"]
        assert main(argv[1:] + ["--json"]) == 1
        alone = json.loads(capsys.readouterr().out)
        assert alone["granted_beyond_m"] == violation["granted_beyond_m"]
        assert (alone["collisions"], alone["authority_overruns"]) == (violation["collisions"],
                                                                      violation["authority_overruns"])
    # the same runs on a local Dask cluster of worker processes: the same table
    distributed = pytest.importorskip("distributed")
    with distributed.LocalCluster(n_workers=2, threads_per_worker=1, processes=True,
                                  dashboard_address=None) as cluster:
        status_dask, on_dask = figures(capsys, SMALL + ["--results", str(tmp_path / "dask.jsonl"),
                                                        "--scheduler", cluster.scheduler_address])
    assert on_dask["runs_made"] == RUNS and status_dask == status
    assert on_dask["by_fault"] == first["by_fault"] and on_dask["violations"] == first["violations"]


def test_a_campaign_over_a_scenario_file_draws_faults_for_its_trains_and_reproduces_each_run(tmp_path, capsys):
    results = str(tmp_path / "r.jsonl")
    argv = ["campaign", "--scenario", "lego_oval_mixed", "--runs", "3", "--duration", "8", "--results", results,
            "--fault", "ips_offset", "--fault", "stop_dead", "--workers", "1"]
    status, out = figures(capsys, argv)
    assert status == 0 and out["runs_made"] == 3
    with open(results) as fh:
        records = [json.loads(line) for line in fh]
    for record in records:
        assert record["command"].startswith("cbtc sim --scenario lego_oval_mixed --seed ")
        for text in record["spec"]["faults"]:
            assert faults.parse(text).params["train"] in ("P1", "F1", "S1")
    again = records[0]
    assert main(shlex.split(again["command"])[1:] + ["--json"]) == 0
    alone = json.loads(capsys.readouterr().out)
    assert alone["granted_beyond_m"] == again["summary"]["granted_beyond_m"]
    assert alone["min_gap_m"] == again["summary"]["min_gap_m"]


@pytest.mark.parametrize("extra,named", [(["--trains", "2"], "--trains: the scenario lego_oval_mixed sets"),
                                         (["--fault", "packed_start"], "sets where the trains start"),
                                         (["--fault", "stop_dead:train=T9"], "no train T9 in scenario")])
def test_a_scenario_campaign_refuses_what_the_file_sets(capsys, extra, named):
    assert main(["campaign", "--scenario", "lego_oval_mixed", "--runs", "2"] + extra) == 2
    assert named in capsys.readouterr().err


def test_a_run_that_raises_is_recorded_as_a_violation_and_the_campaign_goes_on(monkeypatch):
    spec = campaign.plan(2, PATH_CLASSES, ("itb_square",), (2,), 5.0, 0)[0]

    def broken(self):
        raise ZeroDivisionError("float division by zero")
    monkeypatch.setattr(campaign.RunSpec, "config", broken)
    record = campaign.run_one(spec)
    assert record["violations"] == ["raised"] and record["error"] == "ZeroDivisionError: float division by zero"
    table = campaign.tables([spec], {record["command"]: record})
    assert table["runs_with_violations"] == 1 and table["violations"][0]["error"].startswith("ZeroDivision")
    assert table["violations"][0]["command"] == spec.command()
