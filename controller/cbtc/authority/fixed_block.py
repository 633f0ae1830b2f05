"""The fixed-block baseline: block occupancy from track circuits, speed codes, and the same onboard braking curve.

Made to be fair, not a straw man: the same trains, stops, safety margin and onboard supervision as moving block; only
the authority differs. A train may run to the entry of the first occupied block ahead (its signal), less the safety
margin; speed codes descend behind an occupied block as in the BART radio ATC (the block just behind an occupied block
gives the lowest code, restricted speed and a stop at its end; the next one back the approach code; further back line
speed). Each code reaches the train as a Hamming-coded telegram through a noisy channel
(cbtc.authority.speed_code_channel, seed 003); a rejected telegram gives the lowest code. Occupancy comes from track
circuits, which detect any part of a train in a block: in simulation from the trains' true spans (`track_circuits`),
otherwise from the estimates widened by k sigma.
"""

from dataclasses import replace

from cbtc.authority.policy import FIXED_BLOCK
from cbtc.authority.rules import AuthorityParams
from cbtc.authority.speed_code_channel import SpeedCodeChannel
from cbtc.authority.values import Authority, Situation
from cbtc.railway.layout import Block


def equal_blocks(length_m: float, count: int):
    """`count` equal blocks from s = 0 covering a loop of `length_m`."""
    if count < 2:
        raise ValueError(f"fixed blocks: need at least 2 blocks on a loop, got {count}")
    size = length_m / count
    return tuple(Block(f"B{i + 1}", i * size, (i + 1) * size) for i in range(count))


class FixedBlockPolicy:
    """An AuthorityPolicy (cbtc.authority.policy): the entry of the first occupied block ahead bounds the authority."""
    name = FIXED_BLOCK
    title = "fixed block"
    fast_reports = False   # the authority rests on track circuits, not on the train ahead's reports
    needs_spans = True     # the zone passes every train's span (Situation.spans): its occupancy
    uses_blocks = True

    def __init__(self, params: AuthorityParams = None, blocks=None, speed_codes=(0.5, 0.75, 1.0),
                 track_circuits=None, code_ber=0.0, seed=0):
        self.params = params or AuthorityParams()
        self._blocks = blocks              # None: the layout's own; int: that many equal blocks; or a tuple of Block
        # fraction of line speed by clear blocks ahead: [0] = stop at this block's end, [1] = approach, [2+] = line
        self.speed_codes = tuple(speed_codes)
        self.track_circuits = track_circuits  # callable() -> list of (train_id, head_s, tail_s) in truth, or None
        # the rails: every code reaches the train as a Hamming-coded telegram (bit-error rate code_ber); the zone
        # sends through them, the policy only decides
        self.codes = SpeedCodeChannel(code_ber, seed)

    def blocks(self, layout):
        if self._blocks is None:
            if not layout.blocks:
                raise ValueError(f"layout {layout.name} defines no fixed blocks: give a block count")
            return layout.blocks
        if isinstance(self._blocks, int):
            return equal_blocks(layout.length_m, self._blocks)
        return tuple(self._blocks)

    @staticmethod
    def index_at(blocks, layout, s_m):
        for i, b in enumerate(blocks):
            if layout.ahead_m(b.start_m, s_m) < layout.ahead_m(b.start_m, b.end_m):
                return i
        return len(blocks) - 1

    def _taken(self, layout, blocks, spans, exclude_train_id):
        taken = set()
        for train_id, head_s, tail_s in spans:
            if train_id == exclude_train_id:
                continue
            i = self.index_at(blocks, layout, tail_s)
            j = self.index_at(blocks, layout, head_s)
            taken.add(i)
            while i != j:
                i = (i + 1) % len(blocks)
                taken.add(i)
        return taken

    def code(self, sit: Situation):
        """(block index, speed code) the wayside sends `sit.own`'s train from the occupancy in `sit.spans`: the code
        counts the clear blocks ahead, up to line speed. The zone sends it through the rails (`codes`, a noisy
        telegram channel) and passes what the train received as `sit.received_code`."""
        blocks = self.blocks(sit.layout)
        clear_ahead = self.clear_run(sit.layout, blocks, sit.spans, sit.own.train_id, sit.own.s_m)[0]
        return self.index_at(blocks, sit.layout, sit.own.s_m), min(clear_ahead, len(self.speed_codes) - 1)

    def signal(self, sit: Situation) -> Situation:
        """`sit` with the speed code its train received: the code for its block, sent through the rails."""
        block_i, code = self.code(sit)
        return replace(sit, received_code=self.codes.transmit(block_i, code))

    def protected_m(self, layout, train_id, spans) -> float:
        """In truth: to the entry of the first truly occupied block ahead, or to the tail of a train in its own block
        ahead of it, less the safety margin; on a line the end of the track bounds it too."""
        head = next(h for t, h, _ in spans if t == train_id)
        ahead = [layout.ahead_m(head, tail) for t, h, tail in spans if t != train_id and (layout.closed or h > head)]
        if not layout.closed:
            ahead.append(layout.length_m - head)
        blocks = self.blocks(layout)
        to_end_m = layout.ahead_m(head, blocks[self.index_at(blocks, layout, head)].end_m)
        in_block = [d for d in ahead if d < to_end_m]
        if in_block:
            return min(in_block) - self.params.margin_m
        return self.clear_run(layout, blocks, spans, train_id, head)[1] - self.params.margin_m

    def protected_all_m(self, layout, spans) -> list:
        return [self.protected_m(layout, train_id, spans) for train_id, _h, _t in spans]

    def stuck(self, layout, spans):
        """On a loop, when every train starts within the margin of an occupied block ahead, none can ever move (each
        holds a block another needs): the sentence that says so."""
        if not layout.closed or len(spans) < 2:
            return None
        blocks = self.blocks(layout)
        if all(self.clear_run(layout, blocks, spans, train_id, head)[1] <= self.params.margin_m
               for train_id, head, _tail in spans):
            return (f"fixed block: the {len(spans)} trains start on the {len(blocks)} blocks of {layout.name} each at "
                    f"an occupied block, so none can move: give another block count (cbtc sim --blocks)")
        return None

    def authority(self, sit: Situation) -> Authority:
        """The Authority of `sit.own`'s train from the occupancy in `sit.spans` and the speed code it received
        (`sit.received_code`; None: the code sent)."""
        layout = sit.layout
        own = sit.own
        profile = own.profile
        blocks = self.blocks(layout)
        clear_ahead, distance_m, reason = self.clear_run(layout, blocks, sit.spans, own.train_id, own.s_m)
        code = min(clear_ahead, len(self.speed_codes) - 1)
        i = self.index_at(blocks, layout, own.s_m)
        received = code if sit.received_code is None else sit.received_code
        if received < code:
            # a rejected (or lower) code: the train may go only as far as that code allows
            last = i + received if layout.closed else min(i + received, len(blocks) - 1)
            limit_m = layout.ahead_m(own.s_m, blocks[last % len(blocks)].end_m)
            if limit_m < distance_m:
                distance_m, reason = limit_m, f"speed code {received} received for {code}"
        distance_m -= self.params.margin_m + self.params.k_sigma * own.sigma_s_m
        code_mps = self.speed_codes[min(received, len(self.speed_codes) - 1)] * profile.v_max_mps
        return Authority(distance_m, code_mps, profile.accel_max_mps2, profile.beta_s_mps2, f"code {received}",
                         reason)

    def clear_run(self, layout, blocks, spans, train_id, head_s):
        """(clear blocks ahead, distance from the head to the first occupied block's entry, what limits it) for a
        train at `head_s`.

        A block is occupied if any part of another train is in it. If another train stands in the train's own block
        ahead of it, or its span (widened by uncertainty) covers the train's head, the train must stay: (0, 0, ...);
        two trains in one block happen at start-up. Round a loop, the train's own block counts as occupied when
        another train is in it behind the train."""
        i = self.index_at(blocks, layout, head_s)
        to_end_m = layout.ahead_m(head_s, blocks[i].end_m)
        for other, other_head, tail in spans:
            if other != train_id and (0.0 <= layout.ahead_m(head_s, tail) < to_end_m
                                      or 0.0 <= layout.ahead_m(tail, head_s) <= layout.ahead_m(tail, other_head)):
                return 0, 0.0, f"train {other} in its own block"
        taken = self._taken(layout, blocks, spans, train_id)
        clear, j = 0, (i + 1) % len(blocks)
        while True:
            if not layout.closed and j == 0:   # past the last block of a line: its end is the end of the track
                return clear, layout.length_m - head_s, "end of the line"
            if j in taken or j == i:
                break
            clear += 1
            j = (j + 1) % len(blocks)
        if j == i and i not in taken:
            return len(blocks), layout.length_m, "alone on the loop"
        return clear, layout.ahead_m(head_s, blocks[j].start_m), f"block {blocks[j].name} occupied"
