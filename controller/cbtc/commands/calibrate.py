"""`cbtc calibrate encoder|ips|tags`: calibration numbers from a recorded run or hand-measured points.

Reports are JSON lines, one decoded report per line (fields as in docs/protocol.md).
"""

import csv
import json

from cbtc.commands import arg_types
from cbtc.errors import ConfigError
from cbtc.protocol import wire
from cbtc.railway.train_profile import TrainProfile

EXAMPLES = (
    "cbtc calibrate encoder --reports run.jsonl --distance-m 3.20",
    "cbtc calibrate tags --reports run.jsonl --loop-m 6.81 --distance-m 13.62",
)


def register(subparsers):
    p = subparsers.add_parser("calibrate", description=__doc__,
                              help="calibrate the encoder scale, IPS frame or RFID tag positions from recorded data")
    sub = p.add_subparsers(dest="what", metavar="WHAT")
    sub.required = True
    enc = sub.add_parser("encoder", help="find the counts per metre from a run of measured length")
    enc.add_argument("--reports", type=arg_types.input_file, required=True, help="JSON-lines file of the run's reports")
    enc.add_argument("--distance-m", type=arg_types.number(above=0.0, example="3.2"), required=True,
                     help="distance the train really travelled (m)")
    enc.add_argument("--counts-per-m", type=arg_types.number(above=0.0, example="1000"), default=1000.0,
                     help="the counts_per_m the board used during the run (default 1000)")
    enc.add_argument("--train", default=None, metavar="ID", help="the train whose reports to use (a recording of "
                                                                 "several trains needs it)")
    enc.set_defaults(func=_encoder)
    ips = sub.add_parser("ips", help="find the IPS frame (origin, rotation) from points measured in both frames")
    ips.add_argument("--points", type=arg_types.input_file, required=True,
                     help="CSV with header ips_x_mm,ips_y_mm,track_x_m,track_y_m: the hedgehog placed at known spots")
    ips.set_defaults(func=_ips)
    tags = sub.add_parser("tags", help="survey the tag positions along the track from a run's RFID reads")
    tags.add_argument("--reports", type=arg_types.input_file, required=True,
                      help="JSON-lines file of the run's reports")
    tags.add_argument("--start-s-m", type=arg_types.number(minimum=0.0, example="0"), default=0.0,
                      help="track position of the head at the first report (m)")
    tags.add_argument("--loop-m", type=arg_types.number(above=0.0, example="6.8"), default=None,
                      help="loop length (m) for a closed layout")
    tags.add_argument("--distance-m", type=arg_types.number(above=0.0, example="3.2"), default=None,
                      help="distance the train really travelled from the first report to the last (m): the "
                           "odometer's scale is taken from it, as `cbtc calibrate encoder` takes it (default: the "
                           "odometer reads true)")
    tags.add_argument("--rfid-range-m", type=arg_types.number(minimum=0.0, example="0.015"),
                      default=TrainProfile.rfid_range_m,
                      help=f"how far ahead of the head the reader reads a tag (m; default "
                           f"{TrainProfile.rfid_range_m}, the MFRC522 with a LEGO tag)")
    tags.add_argument("--train", default=None, metavar="ID", help="the train whose reports to use (a recording of "
                                                                  "several trains needs it)")
    tags.set_defaults(func=_tags)


MIN_RUN_M = 0.5   # an encoder calibration needs at least this much odometer travel: a count is 1 mm


def _reports(path, train=None):
    """The reports of `path` (of `train` only when given; a recording of several trains needs it)."""
    reports = _all_reports(path)
    ids = sorted({str(r["id"]) for r in reports if "id" in r})
    if train is not None:
        reports = [r for r in reports if str(r.get("id")) == train]
        if not reports:
            raise ConfigError(f"{path}: no reports of train {train}; the trains recorded are {ids}")
    elif len(ids) > 1:
        raise ConfigError(f"{path} holds the reports of trains {ids}: choose one with --train")
    boots = {r.get("boot") for r in reports}
    if len(boots) > 1:
        raise ConfigError(f"{path}: the board restarted during the run (boots {sorted(map(str, boots))}), so its "
                          f"odometer began again: record a run without a restart")
    return reports


def _all_reports(path):
    reports = []
    try:
        with open(path) as fh:
            for number, line in enumerate(fh, 1):
                if line.strip():
                    try:
                        reports.append(json.loads(line))
                    except ValueError as exc:
                        raise ConfigError(f"{path} line {number}: not JSON ({exc}); "
                                          f"one report object per line") from None
    except OSError as exc:
        raise ConfigError(f"cannot read {path}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(_not_text(path, exc, "the JSON-lines file of reports the run recorded")) from None
    if not reports or any(not isinstance(r, dict) or "odo_mm" not in r for r in reports):
        raise ConfigError(f"{path}: expected JSON lines of reports with an 'odo_mm' field")
    for number, report in enumerate(reports, 1):
        tags = report.get("tags", [])
        if not isinstance(tags, list) or any(not isinstance(t, list) or len(t) < 4 or not isinstance(t[0], str)
                                             or not all(isinstance(v, (int, float)) for v in t[1:4]) for t in tags):
            raise ConfigError(f"{path} report {number}: 'tags' must be a list of [uid, odo_mm, t_ms, span_ms, ...] "
                              f"entries (docs/protocol.md, version {wire.VERSION}); record the run again with boards "
                              f"of this version, got {tags!r}")
    return reports


def _not_text(path, exc, want):
    return f"{path} is not UTF-8 text ({exc.reason}); give {want}"


def _encoder(args):
    from cbtc.board.calibration import counts_per_m

    reports = _reports(args.reports, args.train)
    travelled_m = _travelled_m(args, reports)
    counts = travelled_m * args.counts_per_m
    value = counts_per_m([counts], [args.distance_m])
    # the board counts whole counts per metre (its odometer stays an integer): the nearest is within 0.05 % of a
    # scale near 1000, under what the controller's estimator learns anyway
    print(f"odometer {travelled_m:.3f} m for {args.distance_m:.3f} m measured ({value:.1f} counts per m): "
          f"counts_per_m = {round(value)}")
    return 0


def _ips(args):
    from cbtc.board.calibration import align_ips

    ips, track = [], []
    try:
        with open(args.points, newline="") as fh:
            for number, row in enumerate(csv.DictReader(fh), 2):
                try:
                    ips.append((float(row["ips_x_mm"]) / 1000.0, float(row["ips_y_mm"]) / 1000.0))
                    track.append((float(row["track_x_m"]), float(row["track_y_m"])))
                except (KeyError, TypeError, ValueError):
                    raise ConfigError(f"{args.points} line {number}: need numbers in ips_x_mm,ips_y_mm,track_x_m,"
                                      f"track_y_m") from None
    except OSError as exc:
        raise ConfigError(f"cannot read {args.points}: {exc.strerror}") from None
    except UnicodeDecodeError as exc:
        raise ConfigError(_not_text(args.points, exc, "the CSV file of measured points")) from None
    rotation_deg, x_m, y_m, rms_m = align_ips(ips, track)
    print(f"ips:\n  origin_x_m: {x_m:.4f}\n  origin_y_m: {y_m:.4f}\n  rotation_deg: {rotation_deg:.3f}\n"
          f"# rms residual {rms_m * 1000:.1f} mm over {len(ips)} points")
    return 0


def _tags(args):
    from cbtc.board.calibration import survey_tags, tags_yaml

    reports = _reports(args.reports, args.train)
    odo_per_m = 1.0
    if args.distance_m is not None:
        odo_per_m = _travelled_m(args, reports) / args.distance_m
    survey = survey_tags(reports, args.start_s_m, loop_m=args.loop_m, odo_per_m=odo_per_m,
                         read_ahead_m=args.rfid_range_m)
    if not survey:
        raise ConfigError(f"{args.reports}: no tag was read in {len(reports)} reports; record a run that passes "
                          f"over the tags (is the reader wired? `rfid_absent` in the reports' faults says not)")
    print(f"# {len(survey)} tags from {len(reports)} reports, the odometer read {odo_per_m:.4f} m per m")
    print("tags:")
    print(tags_yaml(survey), end="")
    return 0


def _travelled_m(args, reports):
    """Odometer metres between the first report and the last; a run too short to calibrate from is refused."""
    travelled_m = (reports[-1]["odo_mm"] - reports[0]["odo_mm"]) / 1000.0
    if len(reports) < 2 or travelled_m < MIN_RUN_M:
        raise ConfigError(f"{args.reports}: {len(reports)} reports with {travelled_m:.3f} m of odometer between the "
                          f"first and the last; record a run of at least {MIN_RUN_M} m (a few metres is best), from "
                          f"standing to standing, and measure how far the train really went")
    return travelled_m
