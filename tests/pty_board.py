"""A test "board" on a pseudo-terminal: the MicroPython unix port behind a pty, with soft reset emulated.

`PtyBoard(fs_dir, path).start()` exposes `.port` (a /dev/pts/N path) that mpremote and pyserial open like a USB
serial board. Both pty ends are raw (no ONLCR), bytes are copied both ways. The unix port exits where a board would
soft-reset (Ctrl-D at the friendly or raw REPL, machine.reset()): the bridge then prints "soft reboot" and starts a
fresh `micropython -i` in `fs_dir` (the board's filesystem). As on a board: after a reset from the friendly REPL it
runs main.py (if there is one); after a reset from the raw REPL it skips main.py and returns to the raw REPL (the
bridge follows the host's Ctrl-A / Ctrl-B to know which REPL the board is in).
`path` is the MICROPYPATH tail after fs_dir: the host shims and umqtt (frozen on a real board).
"""

import os
import pty
import select
import subprocess
import threading
import tty

from mpy_harness import micropython_argv


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
        self._master, slave = pty.openpty()
        tty.setraw(self._master)
        tty.setraw(slave)
        self.port = os.ttyname(slave)
        self._slave = slave
        self._thread = threading.Thread(target=self._pump, daemon=True)

    def start(self):
        self._spawn(first=True)
        self._thread.start()
        return self

    def _spawn(self, first=False):
        if not first:
            os.write(self._master, b"soft reboot\r\n")
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
                data = os.read(self._master, 4096)
                raw_at, friendly_at = data.rfind(b"\x01"), data.rfind(b"\x02")
                if raw_at != friendly_at:
                    self._raw = raw_at > friendly_at
                try:
                    os.write(self._child_fd, data)
                except OSError:
                    pass
            if self._child_fd in ready:
                try:
                    data = os.read(self._child_fd, 4096)
                except OSError:
                    data = b""
                if data:
                    os.write(self._master, data)
            if self._child.poll() is not None and not self._stop:
                self._drain_and_respawn()

    def _drain_and_respawn(self):
        try:
            while select.select([self._child_fd], [], [], 0)[0]:
                data = os.read(self._child_fd, 4096)
                if not data:
                    break
                os.write(self._master, data)
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
