"""Calibration arithmetic against hand-computed values and the layout's own frame transform; the command on files."""

import json
import math
import re
from types import SimpleNamespace

import numpy as np
import pytest

from cbtc.board.calibration import align_ips, counts_per_m, survey_tags, tags_yaml
from cbtc.cli import main as cli_main
from cbtc.errors import ConfigError
from cbtc.railway.ips_frame import track_to_ips


def test_counts_per_m_is_least_squares_through_the_origin():
    # hand-computed: sum(c d) / sum(d^2) = (1230*1 + 2470*2) / (1 + 4) = 6170 / 5 = 1234
    assert counts_per_m([1230, 2470], [1.0, 2.0]) == pytest.approx(1234.0)
    with pytest.raises(ConfigError, match="> 0"):
        counts_per_m([10], [0.0])


def test_align_ips_recovers_the_layout_frame():
    frame = SimpleNamespace(origin_x_m=-0.1, origin_y_m=0.35, rotation_deg=30.0)
    rng = np.random.default_rng(7)
    track = rng.uniform(-1.0, 2.0, size=(12, 2))
    ips = np.array([track_to_ips(x, y, frame) for x, y in track])
    rotation_deg, x_m, y_m, rms_m = align_ips(ips, track)
    assert rotation_deg == pytest.approx(30.0, abs=1e-9)
    assert (x_m, y_m) == (pytest.approx(-0.1, abs=1e-9), pytest.approx(0.35, abs=1e-9))
    assert rms_m < 1e-9
    noisy = ips + rng.normal(0.0, 0.01, size=ips.shape)     # 1 cm IPS noise: the fit stays within it
    rotation_deg, x_m, y_m, rms_m = align_ips(noisy, track)
    assert abs(rotation_deg - 30.0) < 1.0 and math.hypot(x_m + 0.1, y_m - 0.35) < 0.02 and 0.003 < rms_m < 0.02


def test_survey_tags_from_odometer_reads_on_a_loop():
    reports = [{"odo_mm": 500, "tags": []},
               {"odo_mm": 900, "tags": [["04A1", 800, 10, 0]]},
               {"odo_mm": 4000, "tags": [["04B2", 3900, 20, 0]]},
               {"odo_mm": 5500, "tags": [["04A1", 5404, 30, 0]]}]   # second lap: 5404 - 500 = 4904 mm
    survey = survey_tags(reports, start_s_m=1.0, loop_m=4.6)
    # 04A1: 1.0 + 0.3 = 1.3 and 1.0 + 4.904 - 4.6 = 1.304 -> mean 1.302; 04B2: 1.0 + 3.4 = 4.4
    assert [(uid, round(s, 6), n) for uid, s, n in survey] == [("04A1", 1.302, 2), ("04B2", 4.4, 1)]
    assert tags_yaml(survey).splitlines()[0] == '  - {uid: "04A1", s_m: 1.302}   # 2 reads'


def test_calibrate_command_on_recorded_files(tmp_path, capsys):
    run = tmp_path / "run.jsonl"
    run.write_text("\n".join(json.dumps(r) for r in (
        {"odo_mm": 0, "tags": []}, {"odo_mm": 1900, "tags": [["DEADBEEF", 1500, 5, 0]]}, {"odo_mm": 2100, "tags": []})))
    assert cli_main(["calibrate", "encoder", "--reports", str(run), "--distance-m", "2.0",
                     "--counts-per-m", "1000"]) == 0
    assert "counts_per_m = 1050\n" in capsys.readouterr().out      # 2.1 m counted for 2.0 m travelled
    odd = tmp_path / "odd.jsonl"
    odd.write_text("\n".join(json.dumps({"odo_mm": mm, "tags": []}) for mm in (0, 2087)))
    assert cli_main(["calibrate", "encoder", "--reports", str(odd), "--distance-m", "2.0"]) == 0
    out = capsys.readouterr().out
    assert "1043.5 counts per m" in out and "counts_per_m = 1044\n" in out   # the whole number a board takes
    assert cli_main(["calibrate", "tags", "--reports", str(run), "--start-s-m", "0.25"]) == 0
    # 0.25 + 1.5 m of odometer, and the reader reads 15 mm before its head is over the tag (no speed reported)
    assert '{uid: "DEADBEEF", s_m: 1.765}' in capsys.readouterr().out
    # read 20 ms after the reader's previous poll at 0.4 m/s: the field's edge came up to 8 mm before, 4 on average
    late = tmp_path / "late.jsonl"
    late.write_text("\n".join(json.dumps(r) for r in (
        {"odo_mm": 0, "tags": []}, {"odo_mm": 1900, "v_mmps": 400, "tags": [["DEADBEEF", 1500, 5, 20]]})))
    assert cli_main(["calibrate", "tags", "--reports", str(late), "--start-s-m", "0.25"]) == 0
    assert '{uid: "DEADBEEF", s_m: 1.761}' in capsys.readouterr().out
    # a tag that carries a telegram is read as four fields, as reports carry them now
    run4 = tmp_path / "run4.jsonl"
    telegram = "0123456789abcdef" * 2
    run4.write_text("\n".join(json.dumps(r) for r in (
        {"odo_mm": 0, "tags": []}, {"odo_mm": 1900, "tags": [["DEADBEEF", 1500, 5, 0, telegram]]})))
    assert cli_main(["calibrate", "tags", "--reports", str(run4), "--start-s-m", "0.25", "--rfid-range-m", "0"]) == 0
    assert '{uid: "DEADBEEF", s_m: 1.750}' in capsys.readouterr().out
    assert cli_main(["calibrate", "tags", "--reports", str(run4), "--start-s-m", "0.25", "--rfid-range-m", "0",
                     "--distance-m", "0.95"]) == 0   # 1.9 m of odometer for 0.95 m: it reads double
    assert '{uid: "DEADBEEF", s_m: 1.000}' in capsys.readouterr().out
    odd_tags = tmp_path / "odd_tags.jsonl"
    odd_tags.write_text(json.dumps({"odo_mm": 0, "tags": [["DEADBEEF"]]}))
    assert cli_main(["calibrate", "tags", "--reports", str(odd_tags)]) == 2
    assert "odd_tags.jsonl report 1: 'tags' must be" in capsys.readouterr().err
    points = tmp_path / "points.csv"
    points.write_text("ips_x_mm,ips_y_mm,track_x_m,track_y_m\n0,0,1,2\n1000,0,1,3\n0,1000,0,2\n")
    assert cli_main(["calibrate", "ips", "--points", str(points)]) == 0
    out = capsys.readouterr().out
    assert "origin_x_m: 1.0000" in out and "origin_y_m: 2.0000" in out and "rotation_deg: 90.000" in out
    bad = tmp_path / "bad.jsonl"
    bad.write_text("{not json\n")
    assert cli_main(["calibrate", "tags", "--reports", str(bad)]) == 2
    assert "bad.jsonl line 1" in capsys.readouterr().err


@pytest.mark.parametrize("layout, duration_s", [("straight_test", 20.0), ("itb_square", 40.0)])
def test_a_recorded_simulated_run_calibrates_the_encoder_within_half_a_percent_and_every_tag_within_2_cm(
        layout, duration_s, tmp_path, capsys):
    """What the zone records (`cbtc zone --record`, `cbtc sim --record`: ReportRecording) is what `cbtc calibrate`
    reads: one train runs the 3 m line from standing to standing, or laps the square loop; the board's wheel reads
    2 % long (encoder_scale_error); the truth gives the distance and where the tags are."""
    from cbtc.commands.common import ReportRecording
    from cbtc.sim.runs import sim_config
    from cbtc.sim.simulation import Simulation

    path = str(tmp_path / "run.jsonl")
    config = sim_config(layout, 1, seed=4, duration_s=duration_s)
    sim = Simulation(config, keep_samples=True)
    recording = ReportRecording(path)
    sim.record_reports(recording)
    recorder = sim.run()
    recording.close()
    true_m = recorder.travelled_m[0][-1]
    assert true_m > 2.0
    if layout == "straight_test":   # from standing to standing: the encoder's counts per metre
        assert recorder.v_mps[0][-1] == 0.0
        assert cli_main(["calibrate", "encoder", "--reports", path, "--distance-m", f"{true_m:.4f}"]) == 0
        out = capsys.readouterr().out
        value = float(out.rsplit("counts_per_m = ", 1)[1])
        scale = 1000.0 * (1.0 + config.trains[0].profile.encoder_scale_error)
        assert abs(value - scale) / scale < 0.005, out
    loop = ["--loop-m", f"{config.layout.length_m:.4f}"] if config.layout.closed else []
    assert cli_main(["calibrate", "tags", "--reports", path, "--start-s-m", f"{config.trains[0].s0_m:.4f}",
                     "--distance-m", f"{true_m:.4f}"] + loop) == 0
    out = capsys.readouterr().out
    surveyed = {uid: float(s_m) for uid, s_m in re.findall(r'uid: "(\w+)", s_m: ([\d.]+)', out)}
    truth = {tag.uid: tag.s_m for tag in config.layout.tags}
    assert len(surveyed) >= len(truth) - 1, out   # a passage may miss its read (rfid_miss)
    for uid, s_m in surveyed.items():
        assert abs(s_m - truth[uid]) <= 0.02, (uid, s_m, truth[uid], out)


def test_calibration_refuses_too_little_data_and_an_unchosen_train(tmp_path, capsys):
    one = tmp_path / "one.jsonl"
    one.write_text('{"id": "A", "boot": 1, "odo_mm": 0, "tags": []}\n')
    assert cli_main(["calibrate", "encoder", "--reports", str(one), "--distance-m", "3"]) == 2
    assert "1 reports with 0.000 m of odometer" in capsys.readouterr().err
    two = tmp_path / "two.jsonl"
    two.write_text('{"id": "A", "boot": 1, "odo_mm": 0, "tags": []}\n{"id": "B", "boot": 1, "odo_mm": 900, '
                   '"tags": []}\n')
    assert cli_main(["calibrate", "encoder", "--reports", str(two), "--distance-m", "3"]) == 2
    assert "choose one with --train" in capsys.readouterr().err
    assert cli_main(["calibrate", "encoder", "--reports", str(two), "--distance-m", "3", "--train", "C"]) == 2
    assert "no reports of train C" in capsys.readouterr().err
    assert cli_main(["calibrate", "tags", "--reports", str(one)]) == 2
    assert "no tag was read in 1 reports" in capsys.readouterr().err
    assert cli_main(["calibrate", "tags", "--reports", str(one), "--distance-m", "2"]) == 2
    assert "1 reports with 0.000 m of odometer" in capsys.readouterr().err
