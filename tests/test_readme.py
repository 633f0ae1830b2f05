"""The README is a map: at most 200 lines, a results table whose rows say one figure each in a line or two, and
every document it links to exists."""

import os
import re

ROOT = os.path.dirname(os.path.dirname(os.path.abspath(__file__)))


def test_the_readme_is_a_map():
    text = open(os.path.join(ROOT, "README.md")).read()
    assert len(text.splitlines()) <= 200
    results = text[text.index("## Results"):text.index("## Hardware")]
    rows = [line for line in results.splitlines() if line.startswith("| ") and not line.startswith("| what")]
    assert len(rows) >= 10 and all(len(row) <= 240 for row in rows), max(rows, key=len)
    for link in re.findall(r"\]\(((?:docs/)?[\w./-]+\.(?:md|png))\)", text):
        assert os.path.exists(os.path.join(ROOT, link)), link
