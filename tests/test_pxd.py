"""The compiled build's .pxd files keep in step with their Python source: each class they make a C type declares, as
slots, exactly the attributes its methods set on self, less the names its class body defines (methods, properties,
defaults), which a C type cannot also hold in a slot. A slot left over or missing would not change results (others
go to the instance __dict__) but would fail the build of that module or slow it."""

import ast
import pathlib
import re

import pytest

ROOT = pathlib.Path(__file__).resolve().parents[1]
PXDS = sorted(ROOT.glob("controller/cbtc/**/*.pxd")) + sorted(ROOT.glob("firmware/*.pxd"))


def declared(pxd: pathlib.Path) -> dict:
    """Each class the .pxd declares -> its declarations: the slot names, and "__dict__" / "__weakref__" when it keeps
    them."""
    classes, current = {}, None
    for line in pxd.read_text().splitlines():
        if m := re.match(r"cdef class (\w+):", line):
            current = classes[m.group(1)] = set()
        elif m := re.match(r"\s+cdef public \w+ (.+)", line):
            current.update(name.strip() for name in m.group(1).split(","))
        elif m := re.match(r"\s+cdef (?:dict __dict__|object __weakref__)$", line):
            current.add(line.split()[-1])
    return classes


def stored(source: pathlib.Path, name: str) -> set:
    cls = next(node for node in ast.parse(source.read_text()).body
               if isinstance(node, ast.ClassDef) and node.name == name)
    body = set()
    for item in cls.body:
        if isinstance(item, (ast.FunctionDef, ast.ClassDef)):
            body.add(item.name)
        elif isinstance(item, (ast.Assign, ast.AnnAssign)):
            for target in item.targets if isinstance(item, ast.Assign) else [item.target]:
                body.update(n.id for n in ast.walk(target) if isinstance(n, ast.Name))
    on_self = {n.attr for n in ast.walk(cls) if isinstance(n, ast.Attribute) and isinstance(n.ctx, ast.Store)
               and isinstance(n.value, ast.Name) and n.value.id == "self"}
    return {attr for attr in on_self if attr not in body}


def test_there_are_pxds_for_the_hot_classes():
    names = {p.stem for p in PXDS}
    assert {"controller", "obu", "ukf_estimator", "mock_broker", "simulation"} <= names


@pytest.mark.parametrize("pxd", PXDS, ids=lambda p: str(p.relative_to(ROOT)))
def test_each_pxd_declares_the_attributes_its_class_sets(pxd):
    classes = declared(pxd)
    # a module's .pxd declares its classes, or only C types for functions of the module (cpdef)
    assert classes or "cpdef " in pxd.read_text(), f"{pxd} declares no class and no function"
    for name, names in classes.items():
        # a __weakref__ for whoever holds it weakly; a __dict__ for what else an instance is given, unless the .pxd
        # says its instances hold their slots only (then a cpdef method's call skips the look for an override)
        assert "__weakref__" in names, f"{pxd}: {name} keeps no __weakref__"
        assert "__dict__" in names or "slots only" in pxd.read_text(), f"{pxd}: {name} keeps no __dict__"
        slots = names - {"__dict__", "__weakref__"}
        assert slots == stored(pxd.with_suffix(".py"), name), f"{pxd}: {name}'s slots differ from its source"


def test_every_module_the_build_compiles_is_a_source_file():
    # setup.py's extensions are optional (a module that fails to build stays plain Python), so a misspelt entry
    # would be skipped in silence
    tree = ast.parse((ROOT / "setup.py").read_text())
    compiled = next(node.value for node in tree.body if isinstance(node, ast.Assign)
                    and any(isinstance(t, ast.Name) and t.id == "COMPILED" for t in node.targets))
    names = [elt.value for elt in compiled.elts]
    assert len(names) == len(set(names))
    for name in names:
        path = ROOT / (name if name.startswith("firmware/") else "controller/" + name)
        assert path.is_file(), f"setup.py compiles {name}, which is not a source file"
