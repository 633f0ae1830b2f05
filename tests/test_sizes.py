"""Small rooms: no module of the controller or the firmware over 400 lines, no function over 60, each split by what it
does. The board loads its modules' bytecode onto a heap of ~36 KB, so the firmware's long functions named here stay
whole: their modules' docstrings give the bytes a split was measured to cost (tests/test_heap32.py)."""

import ast
import pathlib
import re

ROOT = pathlib.Path(__file__).resolve().parents[1]
MODULE_LINES = 400
FUNCTION_LINES = 60
# the board's heap pays for every function and module: kept whole, the cost of a split said in the module's docstring
BOARD_WHOLE = {("firmware/obu.py", None), ("firmware/obu.py", "__init__"), ("firmware/obu.py", "_sample"),
               ("firmware/obu.py", "_control"), ("firmware/train.py", "run")}


def _sources():
    for folder in ("controller", "firmware"):
        for path in sorted((ROOT / folder).rglob("*.py")):
            yield path.relative_to(ROOT).as_posix(), path.read_text()


def test_modules_and_functions_are_small_or_say_what_a_split_costs_the_board():
    too_big = []
    for name, text in _sources():
        if len(text.splitlines()) > MODULE_LINES and (name, None) not in BOARD_WHOLE:
            too_big.append(f"{name}: {len(text.splitlines())} lines")
        for node in ast.walk(ast.parse(text)):
            if isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
                lines = node.end_lineno - node.lineno + 1
                if lines > FUNCTION_LINES and (name, node.name) not in BOARD_WHOLE:
                    too_big.append(f"{name}: {node.name} {lines} lines")
    assert not too_big, "split by what it does: " + "; ".join(too_big)


def test_each_function_kept_whole_for_the_board_says_what_its_split_costs():
    for name, function in BOARD_WHOLE:
        doc = ast.get_docstring(ast.parse((ROOT / name).read_text()))
        assert re.search(r"\d+ B\b", doc), f"{name}: no measured bytes"
        assert (f"`{function}`" if function else "module split") in doc, f"{name}: {function or 'the module'} unnamed"
