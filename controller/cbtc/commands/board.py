"""`cbtc board virtual`: a rehearsal board, to try `cbtc flash` and `cbtc calibrate encoder` before the table.

The real firmware under the MicroPython unix port, on a pseudo-terminal that mpremote opens like a board's USB
serial port: it is flashed, resets, boots and reports over MQTT as a NodeMCU does. Its Wi-Fi joins at once and reaches
this machine's brokers; its wheel stands until pushed, then turns as if the train were pushed by hand along the
track, at the wheel's true counts per metre (not the 1000 the firmware starts with: calibration finds it). The
motor drives nothing, and no IPS or RFID is fitted.
"""

import sys

from cbtc.commands import arg_types

EXAMPLES = (
    "cbtc board virtual --fs board --push-m 3.2",
    "cbtc board virtual --push-after-s 20 --push-m 1.0 --counts-per-m 1043 --duration 60",
)


def register(subparsers):
    p = subparsers.add_parser("board", help="start a rehearsal board: the real firmware on the MicroPython unix port",
                              description=__doc__)
    sub = p.add_subparsers(dest="what", metavar="WHAT")
    sub.required = True
    v = sub.add_parser("virtual", help="start a rehearsal board on a pseudo-terminal, for cbtc flash and calibrate",
                       description=__doc__)
    v.add_argument("--fs", type=arg_types.output_folder, default=None, metavar="DIR",
                   help="the board's filesystem, kept after it stops (default: a temporary folder)")
    v.add_argument("--push-m", type=arg_types.number(above=0.0, maximum=100.0, example="3.2"), default=3.2,
                   help="how far the train is pushed along the track (m; default 3.2)")
    v.add_argument("--push-mps", type=arg_types.number(above=0.0, maximum=2.0, example="0.2"), default=0.2,
                   help="how fast it is pushed (m/s; default 0.2)")
    v.add_argument("--push-after-s", type=arg_types.number(minimum=0.0, example="20"), default=None,
                   help="push this many seconds after the firmware has booted (default: when you press Enter)")
    v.add_argument("--counts-per-m", type=arg_types.number(minimum=100.0, maximum=5000.0, example="1040"),
                   default=1040.0, help="the wheel's true encoder counts per metre (default 1040)")
    v.add_argument("--duration", type=arg_types.seconds, default=None,
                   help="stop after this many seconds (default: until Ctrl-C)")
    v.set_defaults(func=run)


def run(args):
    import os
    import select
    import signal
    import tempfile
    import time

    from cbtc.board.umqtt_source import umqtt_simple
    from cbtc.board.virtual_board import PtyBoard, Wheel, build_rehearsal, micropython_exe
    from cbtc.errors import ConfigError

    micropython_exe()
    interactive = args.push_after_s is None
    if interactive and not sys.stdin.isatty():
        raise ConfigError("--push-after-s: stdin is not a terminal, so Enter cannot start the push; give the "
                          "seconds after boot to push at (e.g. --push-after-s 20)")
    umqtt = umqtt_simple()
    with tempfile.TemporaryDirectory(prefix="cbtc-board-") as tmp:
        fs_dir = args.fs or os.path.join(tmp, "fs")
        os.makedirs(fs_dir, exist_ok=True)
        wheel = Wheel(tmp, args.counts_per_m, args.push_m, args.push_mps, args.push_after_s)
        board = PtyBoard(fs_dir, build_rehearsal(os.path.join(tmp, "rom"), wheel, umqtt)).start()
        stop = []
        signal.signal(signal.SIGTERM, lambda *_: stop.append(1))
        when = "press Enter to push it" if interactive else f"it is pushed {args.push_after_s:g} s after it boots"
        print(f"virtual board on {board.port} (files in {fs_dir}); Ctrl-C stops it\n"
              f"  flash it: cbtc flash --port {board.port} --train A --broker mqtt://127.0.0.1:1883 --keys FILE\n"
              f"  its wheel: {args.counts_per_m:g} counts per m; the train stands; once flashed, {when} "
              f"{args.push_m:g} m at {args.push_mps:g} m/s", flush=True)
        end_s = None if args.duration is None else time.monotonic() + args.duration
        said = "standing"
        try:
            while not stop and (end_s is None or time.monotonic() < end_s):
                if interactive and select.select([sys.stdin], [], [], 0.25)[0]:
                    if not sys.stdin.readline():   # the terminal closed: no more Enter to wait for
                        interactive = False
                    elif said != "pushing" and not os.path.exists(wheel.trigger):
                        wheel.push()
                        print("the train will be pushed (once the firmware runs)", flush=True)
                else:
                    time.sleep(0 if interactive else 0.25)
                state, pushed_m, counts = wheel.read()
                if state != said:
                    said = state
                    if state == "pushing":
                        print(f"pushing the train {args.push_m:g} m at {args.push_mps:g} m/s", flush=True)
                    elif state == "pushed":
                        wheel.done()   # a board that boots again stands until pushed again
                        print(f"pushed {pushed_m:.3f} m ({counts} counts); the train stands. Calibrate from the "
                              f"reports recorded meanwhile: cbtc calibrate encoder --reports FILE --distance-m "
                              f"{pushed_m:g}", flush=True)
        except KeyboardInterrupt:
            pass
        finally:
            board.stop()
    print("virtual board: stopped", flush=True)
    return 0
