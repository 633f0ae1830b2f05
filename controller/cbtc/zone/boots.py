"""Which reports of one train move the controller's picture of it forward: boots, sequence and the session echo.

Pure: reports and receive times in, a verdict out. A report of the current boot must come after the last one
(`seq`, wrap-safe), however long the train was silent. A new boot id is a restart of the board, unless it is a boot
the train has left, or the current boot has answered this controller (it is known to be the real board) and the new
one claims an uptime longer than the silence since that boot's last report (a board cannot report before it has
booted, so that is a replay). A report answers this controller when it echoes its session id (`csid`): proof that it
was made after one of this controller's commands reached the board, which no recorded report can give. The boot a
train restarted from joins its left boots only once the new boot has answered, so a replayed boot taking over while
the real board was out of reach never locks the real board out; until then that boot comes back only with reports
after the last one taken from it (what it sent before the restart is a replay).
"""

from cbtc.protocol import wire

wrap_diff = wire.wrap_diff   # named once: a module's attribute is looked up at every use

LEFT_BOOTS = 16          # boots remembered as left: their recorded reports are refused
TWIN_AFTER_MS = 1000     # a boot other than the current one whose reports run this much board time past the first
#                          (or newest taken) of it, while the current boot answers: a second board, alive
TWIN_ALIVE_S = 2.0       # ... the current boot having reported within this long
_BASELINES = 32          # boots whose first (or newest taken) report is remembered for that
UPTIME_SLACK_S = 0.5     # a new boot's uptime may exceed the silence by this, plus 2 % of it (clock rates differ)


class BootTracker:
    def __init__(self):
        self.boot = None         # boot id of the accepted reports
        self.last_seq = None     # and the newest accepted seq of that boot
        self.last_recv_s = None
        self.answered = False    # the newest accepted report echoes this controller's session
        self.left = ()           # boots this train has left, newest last
        self._leaving = None     # the boot a restart came from, until the new boot has answered
        self._leaving_seq = None  # and its last accepted seq
        self.twins = set()       # boots shown to be a second board reporting under this train's id
        self._baselines = {}     # boot -> (seq, t_ms): its newest report taken, or the first seen of a boot not taken

    def second_board(self, report, recv_s):
        """True when `report` (authenticated) comes from a second board under this train's id: a boot other than the
        current one, reporting TWIN_AFTER_MS of its own board time past its newest report taken (or the first seen
        of it), with later sequence numbers, while the current boot answers this controller and reported within
        TWIN_ALIVE_S: a replay repeats what was sent, a board that restarted stops, so two boards are alive. Once
        shown, every report of that boot is the second board's."""
        boot = report["boot"]
        if boot in self.twins:
            return True
        if self.boot is None or boot == self.boot:
            return False
        base = self._baselines.get(boot)
        if base is None:
            self._remember(boot, report)
            return False
        alive = self.answered and self.last_recv_s is not None and recv_s - self.last_recv_s <= TWIN_ALIVE_S
        if alive and wrap_diff(report["seq"], base[0]) > 0 and wrap_diff(report["t_ms"], base[1]) >= TWIN_AFTER_MS:
            self.twins.add(boot)
            return True
        return False

    def _remember(self, boot, report):
        baselines = self._baselines
        baselines.pop(boot, None)
        baselines[boot] = (report["seq"], report["t_ms"])
        if len(baselines) > _BASELINES:
            del baselines[next(iter(baselines))]

    def refusal(self, report, recv_s):
        """Why `report` (received at `recv_s`) must be dropped, or "" if it moves the picture forward."""
        boot = report["boot"]
        if boot == self.boot:
            if self.last_seq is not None and wrap_diff(report["seq"], self.last_seq) <= 0:
                return f"report seq {report['seq']} not after {self.last_seq} (replayed or reordered)"
            return ""
        if boot in self.left:
            return f"report of boot {boot}, which this train has left (replayed from before a restart)"
        if boot == self._leaving and wrap_diff(report["seq"], self._leaving_seq) <= 0:
            return f"report seq {report['seq']} of boot {boot}, the boot before the restart (a replay)"
        if self.answered and self.last_recv_s is not None:
            silence_s = recv_s - self.last_recv_s
            if report["t_ms"] / 1000.0 > silence_s * 1.02 + UPTIME_SLACK_S:
                return (f"report of boot {boot} claims {report['t_ms'] / 1000.0:.1f} s of uptime, but boot "
                        f"{self.boot} reported {silence_s:.1f} s ago (a replay, not a restart)")
        return ""

    def accept(self, report, recv_s, session_id):
        """Take a report `refusal` passed; True if it starts a new boot after another (a restart of the board)."""
        restart = self.boot is not None and report["boot"] != self.boot
        if restart and self._leaving is None and self.answered:
            self._leaving, self._leaving_seq = self.boot, self.last_seq
        self.boot = report["boot"]
        self.last_seq = report["seq"]
        self._remember(self.boot, report)
        self.last_recv_s = recv_s
        self.answered = report["csid"] == session_id
        if self.answered and self._leaving is not None:
            if self._leaving != self.boot:
                self.left = (self.left + (self._leaving,))[-LEFT_BOOTS:]
            self._leaving = None
        return restart
