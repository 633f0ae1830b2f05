"""Property-based tests of every parser that meets outside data (properties in tests/properties.py and, for the
board's parsers, tests/mpy/fuzz_cases.py).

Bounded in the normal suite (derandomized: the same examples on every run); `pytest -m fuzz` runs the long profile
with fresh examples. The board's parsers (command decoding, the IPS frame parser, the MFRC522 driver) also run the
generated cases under the MicroPython unix port, which must reach the same outcome as CPython on each.
"""

import json
import struct
import sys

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import properties as p
from cbtc.estimation.odometry_estimator import OdometryEstimator
from cbtc.firmware import obu
from cbtc.firmware.manifest import FIRMWARE_DIR
from cbtc.layout_files import load_layout
from cbtc.zone.boots import LEFT_BOOTS
from cbtc.zone.controller import ZoneController
from cbtc.zone.train_state import TrainSetup
from fake_drivers import FakeEncoder, FakeIps, FakeMotor, FakeRfid
from mpy_harness import MPY_TESTS_DIR, SHIMS_DIR, requires_micropython, run_micropython

for _folder in (SHIMS_DIR, MPY_TESTS_DIR, FIRMWARE_DIR):
    if _folder not in sys.path:
        sys.path.insert(0, _folder)

import fuzz_cases  # noqa: E402  (needs the shims and the firmware on the path)
from check_ips import frame, position  # noqa: E402

BOUNDED = settings(max_examples=200, deadline=None, derandomize=True, database=None,
                   suppress_health_check=[HealthCheck.too_slow])
LONG = settings(max_examples=5000, deadline=None, suppress_health_check=[HealthCheck.too_slow])

garbage = st.binary(max_size=40)
ips_streams = st.lists(st.one_of(
    st.builds(position, st.integers(-2 ** 31, 2 ** 31 - 1), st.integers(-2 ** 31, 2 ** 31 - 1),
              st.integers(-2 ** 31, 2 ** 31 - 1)),
    st.builds(frame, st.integers(0, 0xFFFF), st.binary(max_size=70)),
    st.builds(lambda n, tail: bytes([0xFF, 0x47, 0x11, 0x00, n]) + tail, st.integers(0, 255), garbage),
    garbage), max_size=8).flatmap(
    lambda parts: st.lists(st.integers(1, 80), min_size=1, max_size=10).map(lambda cuts: _chunks(b"".join(parts),
                                                                                                  cuts)))
chip_answers = st.lists(st.integers(-1, 255), min_size=1, max_size=60)
command_payloads = st.one_of(
    p.command_fields.map(p.encode_command),
    p.mutated_bodies(p.command_fields, p.encode_command).map(
        lambda body: p.wire.seal(p.KEY, p.CMD_TOPIC, json.dumps(body).encode())),
    st.binary(max_size=120).map(lambda raw: p.wire.seal(p.KEY, p.CMD_TOPIC, raw)),
    st.binary(max_size=120))


def _chunks(data, cuts):
    out, i, k = [], 0, 0
    while i < len(data):
        step = cuts[k % len(cuts)]
        out.append(data[i:i + step])
        i += step
        k += 1
    return out or [b""]


def ips_fixes_are_frames_sent(chunks):
    """Every fix returned is a whole position frame with a good CRC that was in the stream; none is invented."""
    fixes, frames_ok, _crc, _other = fuzz_cases.ips_outcome(chunks)
    data = b"".join(chunks)
    sent = set()
    for i in range(len(data) - 28):
        raw = data[i:i + 29]
        if raw[:5] == bytes([0xFF, 0x47, 0x11, 0x00, 22]) and frame(0x0011, raw[5:27]) == raw:
            sent.add(struct.unpack_from("<iiiB", raw, 9))
    assert {tuple(fix[1:]) for fix in fixes if fix is not None} <= sent
    assert frames_ok >= sum(fix is not None for fix in fixes)


def ips_every_frame_between_clean_gaps_is_returned_when_complete(xs, gap):
    gap = gap.replace(b"\xff", b"")            # no sync byte in the gaps: nothing can look like a header
    chunks = []
    for x in xs:
        chunks += [gap, position(x, -x, 7)]
    fixes = fuzz_cases.ips_outcome(chunks)[0]
    assert [f[1] for f in fixes[1::2]] == xs and fixes[0::2] == [None] * len(xs)


def mfrc522_answers_are_a_uid_a_reader_gives_or_nothing(answers):
    out = fuzz_cases.mfrc522_outcome(answers, 6)
    for item in out[1:]:
        if item != "bus error":
            uid, data = item
            assert uid is None or p._hex(uid, p.wire_zc.UID_HEX_LENGTHS) and uid == uid.upper(), uid
            assert data is None or p._hex(data, (32,))


cards = st.tuples(st.sampled_from([4, 7, 10]).flatmap(lambda n: st.binary(min_size=n, max_size=n)),
                  st.sampled_from([0x00, 0x08, 0x20, 0x04]), st.binary(min_size=180, max_size=180), st.integers(0, 3))


def a_card_reads_as_its_uid_or_nothing(card):
    """A card in the field reads as its whole uid (upper-case hex) or not at all; a Type 2 card's pages with it."""
    uid, sak, memory, corrupt = card
    read, data = fuzz_cases.card_outcome(*card)
    if corrupt & 1 or sak & 0x04:                # a wrong BCC, or a SAK that claims more levels than the card has
        assert read is None
    else:
        assert read == uid.hex().upper(), (read, uid)
        assert data == (memory[16:32].hex() if sak == 0x00 and not corrupt & 2 else None)


def command_payload_is_refused_or_conforms(payload):
    verdict, value = fuzz_cases.command_outcome(payload)
    assert verdict == "refused" and value or p.command_conforms(dict(value))


command_actions = st.lists(st.one_of(
    st.tuples(st.just("step"), st.integers(1, 200)), st.tuples(st.just("fresh"), st.integers(-5000, 20000)),
    st.tuples(st.just("replay"), st.integers(0, 10 ** 6)), st.tuples(st.just("reboot"), st.just(0)),
    st.tuples(st.just("session"), st.just(0)), st.tuples(st.just("forged"), st.just(0))), max_size=60)


def the_board_takes_exactly_the_fresh_authentic_commands(actions):
    """A board fed fresh commands of a controller that may restart, replays of any command sent before (of earlier
    boots and sessions too), forgeries, and reboots of its own: it takes every fresh command the rules allow (a new
    session needs a newer report; none rests on a report from before its encoder failed) and nothing else."""
    reports = []

    def boot(boot_id):
        reports.clear()
        unit = obu.OnboardUnit("A", p.KEY, boot_id, FakeEncoder(), FakeIps(), FakeRfid(), FakeMotor(),
                               lambda topic, payload: reports.append(payload), {"counts_per_m": 1000})
        unit.step(0)
        return unit

    unit, boot_id, now = boot(1), 1, 0
    sid, seq, sent = 1000, 0, []
    cur_sid, cur_rseq = -1, None                   # the model of what the board holds
    for kind, arg in actions:
        if kind == "step":
            now += arg
            unit.step(now)
            continue
        if kind == "reboot":
            boot_id += 1
            unit, now, cur_sid, cur_rseq = boot(boot_id), 0, -1, None
            continue
        if kind == "session":
            sid, seq = sid + 1, 0
            continue
        report = p.wire_zc.decode_report(p.KEY, p.REPORT_TOPIC, reports[-1])
        if kind == "replay":
            if not sent:
                continue
            payload, expect = sent[arg % len(sent)], False
        else:
            seq += 1
            key = p.KEY if kind == "fresh" else b"not the key 1234"
            payload = p.wire_zc.encode_command(key, "A", report["boot"], seq, sid, report["seq"], 500, arg, 800, 600,
                                            800)
            expect = kind == "fresh" and (sid == cur_sid or cur_rseq is None or report["seq"] > cur_rseq)
            # a board driven with no counts finds its encoder failed: the odometer of earlier reports is lost
            expect = expect and (unit.enc_fail_ms is None or p.wire.wrap_diff(report["t_ms"], unit.enc_fail_ms) > 0)
            sent.append(payload)
        before = unit.rejected
        unit.on_message(p.CMD_TOPIC, payload, now)
        assert (unit.rejected == before) == expect, (kind, unit.last_reject)
        if expect:
            cur_sid, cur_rseq = sid, report["seq"]
            assert unit.sid == sid and unit.eoa_mm == arg


report_actions = st.lists(st.one_of(
    st.tuples(st.just("fresh"), st.integers(1, 200)), st.tuples(st.just("replay"), st.integers(0, 10 ** 6)),
    st.tuples(st.just("reboot"), st.integers(1, 5000)), st.tuples(st.just("silence"), st.integers(1, 20000))),
    max_size=60).filter(lambda actions: sum(kind == "reboot" for kind, _ in actions) < LEFT_BOOTS)


def the_zone_takes_exactly_the_fresh_reports(actions):
    """A zone controller fed a board's reports (answering it: they echo its session), replays of any report sent
    before (of earlier boots too, after any silence) and reboots of the board, each taking `arg` ms: it takes every
    fresh report and no replay; a new boot is a restart."""
    now = [0.0]
    zc = ZoneController(load_layout("itb_square"), [TrainSetup("A", p.KEY)], _NullBus(), lambda: now[0],
                        policy=None, estimator_factory=OdometryEstimator, event_driven=False)
    state = zc.state_of("A")
    boot_id, seq, t_ms, sent, restarts, rebooted = 1, 0, 0, [], 0, False
    for kind, arg in actions:
        if kind == "silence":
            now[0] += arg / 1000.0
            continue
        if kind == "reboot":
            boot_id, seq, t_ms, rebooted = boot_id + 1, 0, 0, bool(sent)
            now[0] += arg / 1000.0
            continue
        if kind == "replay":
            if not sent:
                continue
            payload, expect = sent[arg % len(sent)], False
        else:
            now[0] += arg / 1000.0
            t_ms += arg
            payload, expect = p.wire.encode_report(p.KEY, "A", boot_id, seq, t_ms, seq, 0, 0, "idle", 1, zc.session_id,
                                                   None, [], []), True
            seq += 1
            sent.append(payload)
            restarts, rebooted = restarts + rebooted, False
        before = state.reports_rejected
        zc.on_report(p.REPORT_TOPIC, payload)
        assert (state.reports_rejected == before) == expect, (kind, state.last_reject)
    assert zc.invalid_reports == 0 and state.restarts == restarts


class _NullBus:
    def subscribe(self, topic, handler):
        pass

    def publish(self, topic, payload, retain=False):
        pass


PROPERTIES = {
    "zone_report_stream": (the_zone_takes_exactly_the_fresh_reports, report_actions),
    "board_command_stream": (the_board_takes_exactly_the_fresh_authentic_commands, command_actions),
    "report_round_trip": (p.report_round_trip, p.report_fields),
    "command_round_trip": (p.command_round_trip, p.command_fields),
    "mutated_report": (p.mutated_report_is_refused_or_conforms, p.mutated_bodies(p.report_fields, p.encode_report)),
    "mutated_command": (p.mutated_command_is_refused_or_conforms,
                        p.mutated_bodies(p.command_fields, p.encode_command)),
    "any_bytes": (p.any_bytes_are_refused_with_a_reason, st.binary(max_size=200), st.booleans()),
    "telegram_round_trip": (p.telegram_round_trip_corrects_one_error_and_detects_two, st.binary(min_size=1, max_size=8),
                            st.tuples(st.integers(0, 10 ** 6), st.integers(0, 10 ** 6))),
    "telegram_any_bits": (p.telegram_decodes_any_bits_without_surprise, st.lists(st.integers(0, 1), max_size=200)),
    "ips_stream": (ips_fixes_are_frames_sent, ips_streams),
    "ips_clean_gaps": (ips_every_frame_between_clean_gaps_is_returned_when_complete,
                       st.lists(st.integers(-10 ** 6, 10 ** 6), min_size=1, max_size=5), garbage),
    "mfrc522": (mfrc522_answers_are_a_uid_a_reader_gives_or_nothing, chip_answers),
    "mfrc522_card": (a_card_reads_as_its_uid_or_nothing, cards),
    "board_command": (command_payload_is_refused_or_conforms, command_payloads),
    "layout": (p.layout_mutation_loads_or_names_the_problem,
               st.sampled_from(["itb_square", "lego_oval", "straight_test", "lego_passing_loop", "lego_branch",
                                "lego_figure_eight"]),
               st.lists(st.integers(0, 50), min_size=1, max_size=4), p.json_values),
}


@pytest.mark.parametrize("name", sorted(PROPERTIES))
def test_property(name):
    prop, *strategies = PROPERTIES[name]
    BOUNDED(given(*strategies)(prop))()


@pytest.mark.fuzz
@pytest.mark.parametrize("name", sorted(PROPERTIES))
def test_property_long(name):
    prop, *strategies = PROPERTIES[name]
    LONG(given(*strategies)(prop))()


def _cases(strategy, n):
    """`n` generated values of `strategy`, the same on every run."""
    found = []

    def keep(value):
        found.append(value)

    settings(max_examples=n, deadline=None, derandomize=True, database=None,
             suppress_health_check=list(HealthCheck))(given(strategy)(keep))()
    return found


@requires_micropython
@pytest.mark.parametrize("kind, strategy, outcome", [
    ("command", command_payloads, fuzz_cases.command_outcome),
    ("ips", ips_streams, fuzz_cases.ips_outcome),
    ("mfrc522", st.tuples(chip_answers, st.just(6)), lambda case: fuzz_cases.mfrc522_outcome(*case)),
    ("card", cards, lambda case: fuzz_cases.card_outcome(*case)),
])
def test_the_board_parsers_reach_the_same_outcome_under_micropython(mpy_tree, kind, strategy, outcome):
    cases = _cases(strategy, 150)
    expected = [json.loads(json.dumps(outcome(case))) for case in cases]
    script = "import fuzz_cases\nfuzz_cases.run(%r, %r)\n" % (kind, cases)
    # the cases come as one literal in the script, compiled in the heap: room for that, not a board's figure (the
    # port's GC scans its C stack conservatively, so at 256K a stale pointer now and then ran it out of memory)
    rc, out, err = run_micropython(mpy_tree, script, heap="1M")
    assert rc == 0, out[-2000:] + err[-2000:]
    got = [json.loads(line) for line in out.splitlines()]
    assert len(got) == len(cases)
    for case, want, have in zip(cases, expected, got):
        if want[0] == "refused" and kind == "command":   # both refuse; the words may quote values differently
            assert have[0] == "refused" and have[1], (case, have)
        else:
            assert have == want, case
