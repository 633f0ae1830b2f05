"""`cbtc zone`'s status: a table of at most 100 columns however many trains, each train's authority and what
limits it (or why it is held), stale data marked stale, and a legend."""

from cbtc.commands.zone import STATUS_LEGEND, status_table
from cbtc.sim.runs import sim_config
from cbtc.sim.simulation import Simulation


def test_twelve_trains_fit_100_columns_with_their_authority_and_a_stale_one_marked():
    sim = Simulation(sim_config("lego_long_oval", 12, seed=3, duration_s=30.0))
    sim.scheduler.run_until(0.5)
    held = status_table(sim.zc.view(0.5), True)   # while a train is not located yet: every train held
    sim.scheduler.run_until(12.0)
    sim.trains[5].frozen = True          # a dead board: its reports stop
    sim.scheduler.run_until(14.0)
    lines = status_table(sim.zc.view(14.0), True)
    assert all(len(line) <= 100 for line in lines + held), "\n".join(lines)
    rows = _rows(lines)
    assert len(rows) == 12 and "~" not in "".join(lines), "\n".join(lines)
    dead = sim.trains[5].train_id
    assert "STALE" in rows[dead] and all("STALE" not in row for t, row in rows.items() if t != dead)
    assert any("'s tail" in row for row in rows.values())              # what limits a follower
    assert any("held: T3 not located" in row for row in _rows(held).values()), "\n".join(held)
    for word in ("s = head position", "limit = end of authority", "STALE", "authority = what limits"):
        assert word in STATUS_LEGEND


def _rows(lines):
    """{train: its row's text}: a row's wrapped lines (those starting with a blank train column) joined to it."""
    rows, last = {}, None
    for line in lines[2:]:
        if not line.startswith(" "):
            last = line.split()[0]
            rows[last] = line
        else:
            rows[last] += " " + line.strip()
    return rows


def test_a_long_authority_reason_wraps_whole_words_below_its_row():
    from cbtc.commands.zone import STATUS_COLUMNS, _row
    start = sum(width + 1 for _name, width, _align in STATUS_COLUMNS[:7])
    reason = "horizon (train B's tail further back than its length)"
    lines = _row(("A", "1.00", "0.30", "2.00", "0.05", "run", "north", reason, "-"))
    assert len(lines) > 1 and all(len(line) <= 100 for line in lines)
    assert " ".join(line[start:start + 30].strip() for line in lines).split() == reason.split()
