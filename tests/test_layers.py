"""The layer contract of ``src/gradgps``, read from the source (AST), not from imports at run time.

Every module belongs to a layer: the ground modules (``_exceptions``,
``_result``, ``_version``), one of the private subpackages, or the public
face (``gradgps``, ``gradgps.metrics``, ``gradgps.__main__``). A module may
import from its own layer and from the layers that ``ALLOWED`` lists for it,
nothing else; so imports only go downward:

    ground < _tracks < _io, _grad, _data < _baselines < _train < _eval
                       _io, _grad < _run;   everything < _cli < the public face

Imports inside functions count (they are imports all the same), and so do
``if TYPE_CHECKING:`` ones. Also checked: no import cycles between modules,
no import of an underscore name from another layer, nor a use of one as
``module._name`` (make the name public within the private package, or
move the code), and at most
``MAX_LAYERS`` modules on the longest import chain.
"""

from __future__ import annotations

import ast
import functools
from pathlib import Path

import pytest

SRC = Path(__file__).resolve().parents[1] / "src"
PACKAGE = "gradgps"

GROUND = frozenset({"gradgps._exceptions", "gradgps._result", "gradgps._version"})
FACE = frozenset(
    {
        "gradgps",
        "gradgps.__main__",
        "gradgps._public",
        "gradgps.datasets",
        "gradgps.inject",
        "gradgps.metrics",
        "gradgps.simulate",
    }
)

# layer -> the layers it may import from (besides itself).
ALLOWED: dict[str, frozenset[str]] = {
    "ground": frozenset(),
    "_tracks": frozenset({"ground"}),
    "_io": frozenset({"ground", "_tracks"}),
    "_grad": frozenset({"ground", "_tracks"}),
    "_data": frozenset({"ground", "_tracks"}),
    "_baselines": frozenset({"ground", "_tracks", "_grad"}),
    "_train": frozenset({"ground", "_tracks", "_grad", "_data", "_baselines"}),
    "_eval": frozenset({"ground", "_tracks", "_grad", "_data", "_baselines", "_train"}),
    "_run": frozenset({"ground", "_tracks", "_io", "_grad"}),
    "_cli": frozenset(
        {"ground", "_tracks", "_io", "_grad", "_data", "_baselines", "_train", "_eval", "_run"}
    ),
    "face": frozenset(
        {
            "ground",
            "_tracks",
            "_io",
            "_grad",
            "_data",
            "_baselines",
            "_train",
            "_eval",
            "_run",
            "_cli",
        }
    ),
}

# The algorithm core stays usable without training, evaluation, runners or the CLI.
GRAD_NEVER_IMPORTS = frozenset({"_train", "_eval", "_run", "_data", "_baselines", "_cli"})

# Modules on the longest import chain (``__main__`` is run, never imported, so it is left out).
MAX_LAYERS = 9


def _module_name(path: Path) -> str:
    parts = list(path.relative_to(SRC).with_suffix("").parts)
    if parts[-1] == "__init__":
        parts.pop()
    return ".".join(parts)


@functools.cache
def _modules() -> dict[str, Path]:
    return {_module_name(p): p for p in sorted((SRC / PACKAGE).rglob("*.py"))}


def layer(module: str) -> str:
    if module in FACE:
        return "face"
    if module in GROUND:
        return "ground"
    parts = module.split(".")
    if len(parts) >= 3 or (module in _modules() and _modules()[module].name == "__init__.py"):
        return parts[1]
    return module  # a module outside every layer: the table does not know it


@functools.cache
def imports() -> dict[str, list[tuple[str, str | None, int]]]:
    """module -> [(imported module, imported name or None, line)] for every gradgps import."""
    mods = _modules()
    out: dict[str, list[tuple[str, str | None, int]]] = {}
    for mod, path in mods.items():
        package = mod if path.name == "__init__.py" else mod.rpartition(".")[0]
        found: list[tuple[str, str | None, int]] = []
        for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"), str(path))):
            if isinstance(node, ast.Import):
                found += [(a.name, None, node.lineno) for a in node.names if _ours(a.name)]
            elif isinstance(node, ast.ImportFrom):
                if node.level:
                    base = package.split(".")[: len(package.split(".")) - (node.level - 1)]
                    target = ".".join([*base, node.module] if node.module else base)
                else:
                    target = node.module or ""
                if not _ours(target):
                    continue
                for alias in node.names:
                    sub = f"{target}.{alias.name}"
                    if sub in mods:  # ``from package import module``
                        found.append((sub, None, node.lineno))
                    else:
                        found.append((target, alias.name, node.lineno))
        out[mod] = found
    return out


def _ours(name: str) -> bool:
    return name == PACKAGE or name.startswith(PACKAGE + ".")


def graph() -> dict[str, set[str]]:
    return {
        mod: {target for target, _, _ in found if target != mod} for mod, found in imports().items()
    }


def test_every_module_is_seen() -> None:
    mods = _modules()
    assert len(mods) > 50
    missing = sorted(t for found in imports().values() for t, _, _ in found if t not in mods)
    assert not missing, f"imports of modules that do not exist: {missing}"


def test_every_module_belongs_to_a_known_layer() -> None:
    unknown = sorted(m for m in _modules() if layer(m) not in ALLOWED)
    assert not unknown, (
        f"modules outside every layer (put them in a subpackage, or add it to ALLOWED): {unknown}"
    )


def test_imports_go_only_downward() -> None:
    wrong = [
        f"{mod} ({layer(mod)}) imports {target} ({layer(target)}) at line {line}"
        for mod, found in imports().items()
        for target, _, line in found
        if layer(target) != layer(mod) and layer(target) not in ALLOWED.get(layer(mod), ())
    ]
    assert not wrong, "imports against the layer order:\n" + "\n".join(wrong)


def test_the_algorithm_core_imports_nothing_above_it() -> None:
    wrong = [
        f"{mod} imports {target}"
        for mod, found in imports().items()
        if layer(mod) == "_grad"
        for target, _, _ in found
        if layer(target) in GRAD_NEVER_IMPORTS
    ]
    assert not wrong


def test_no_underscore_name_crosses_a_layer() -> None:
    wrong = [
        f"{mod} imports {name} from {target} at line {line}"
        for mod, found in imports().items()
        for target, name, line in found
        if name is not None and name.startswith("_") and not name.startswith("__")
        if layer(target) != layer(mod)
    ]
    assert not wrong, "make these public within the private package, or move the code:\n" + (
        "\n".join(wrong)
    )


def private_attributes(mod: str, source: str) -> list[tuple[str, int]]:
    """``module._name`` uses in ``source`` (module ``mod``) of a gradgps module it imported:
    an underscore import by another road (``from .. import x`` then ``x._private``)."""
    mods = _modules()
    package = mod if mods[mod].name == "__init__.py" else mod.rpartition(".")[0]
    tree = ast.parse(source)
    bound: dict[str, str] = {}  # local name -> the gradgps module it names
    for node in ast.walk(tree):
        if isinstance(node, ast.Import):
            for a in node.names:
                if _ours(a.name):
                    bound[a.asname or PACKAGE] = a.name if a.asname else PACKAGE
        elif isinstance(node, ast.ImportFrom):
            base = package.split(".")[: len(package.split(".")) - max(node.level - 1, 0)]
            target = ".".join([*base, node.module] if node.module else base)
            target = target if node.level else node.module or ""
            for a in node.names:
                if f"{target}.{a.name}" in mods:
                    bound[a.asname or a.name] = f"{target}.{a.name}"
    found = []
    for node in ast.walk(tree):
        if not (isinstance(node, ast.Attribute) and node.attr.startswith("_")):
            continue
        if node.attr.startswith("__"):
            continue
        path, value = [], node.value
        while isinstance(value, ast.Attribute):
            path.insert(0, value.attr)
            value = value.value
        if isinstance(value, ast.Name) and value.id in bound:
            target = ".".join([bound[value.id], *path])
            if target in mods:
                found.append((f"{target}.{node.attr}", node.lineno))
    return found


def test_no_private_attribute_crosses_a_layer() -> None:
    wrong = [
        f"{mod} uses {name} at line {line}"
        for mod, path in _modules().items()
        for name, line in private_attributes(mod, path.read_text(encoding="utf-8"))
        if layer(name.rpartition(".")[0]) != layer(mod)
    ]
    assert not wrong, "make these public within the private package, or move the code:\n" + (
        "\n".join(wrong)
    )


def test_a_private_attribute_use_is_seen() -> None:
    source = (
        "from .._grad import detector\n"
        "import gradgps._tracks.geo as geo\n"
        "detector._hidden(geo._frame, detector.Detector)\n"
    )
    assert private_attributes("gradgps._run.follow", source) == [
        ("gradgps._grad.detector._hidden", 3),
        ("gradgps._tracks.geo._frame", 3),
    ]


def _cycle(edges: dict[str, set[str]]) -> list[str] | None:
    state: dict[str, int] = {}  # 1 on the stack, 2 done
    stack: list[str] = []

    def visit(mod: str) -> list[str] | None:
        state[mod] = 1
        stack.append(mod)
        for target in sorted(edges.get(mod, ())):
            if state.get(target) == 1:
                return [*stack[stack.index(target) :], target]
            if target not in state and (found := visit(target)):
                return found
        stack.pop()
        state[mod] = 2
        return None

    for mod in sorted(edges):
        if mod not in state and (found := visit(mod)):
            return found
    return None


def test_no_import_cycles() -> None:
    cycle = _cycle(graph())
    assert cycle is None, "import cycle: " + " -> ".join(cycle or [])


def longest_chain() -> list[str]:
    edges = graph()
    assert _cycle(edges) is None

    @functools.cache
    def chain(mod: str) -> tuple[str, ...]:
        below = [chain(t) for t in edges.get(mod, ())]
        return (mod, *max(below, key=len, default=()))

    return list(max((chain(m) for m in edges if m != "gradgps.__main__"), key=len))


def test_import_chains_are_short() -> None:
    longest = longest_chain()
    assert len(longest) <= MAX_LAYERS, f"{len(longest)} layers: " + " -> ".join(longest)


@pytest.mark.parametrize(
    ("module", "expected"),
    [
        ("gradgps._exceptions", "ground"),
        ("gradgps._grad", "_grad"),
        ("gradgps._grad.detector", "_grad"),
        ("gradgps._cli.detect", "_cli"),
        ("gradgps.metrics", "face"),
        ("gradgps._detector", "gradgps._detector"),  # a flat module: in no layer
    ],
)
def test_layer_of(module: str, expected: str) -> None:
    assert layer(module) == expected


def test_public_names_report_the_public_module() -> None:
    import gradgps

    for name in gradgps.__all__:
        obj = getattr(gradgps, name)
        if isinstance(obj, type):
            assert obj.__module__ == "gradgps", name
            assert getattr(gradgps, obj.__qualname__) is obj  # pickle finds it there
    for module in (gradgps.simulate, gradgps.inject, gradgps.datasets, gradgps.metrics):
        assert module.__all__, module
        for name in module.__all__:
            obj = getattr(module, name)
            if callable(obj):
                assert obj.__module__ == module.__name__, (module.__name__, name)
                assert getattr(module, obj.__qualname__) is obj


def test_product_and_evaluation_kit_are_split() -> None:
    import gradgps

    assert {"Detector", "MultiTrackDetector", "read_fixes", "PointResult", "InputError"} <= set(
        gradgps.__all__
    )
    for kit in ("simulate_drive", "inject_grad", "load_dataset", "class_scores"):
        assert kit not in gradgps.__all__, kit
    # Older code keeps working: the kit's names and the old multi-track name still import.
    assert gradgps.simulate_drive is gradgps.simulate.simulate_drive
    assert gradgps.load_dataset is gradgps.datasets.load_dataset
    assert gradgps.TrackStreams is gradgps.MultiTrackDetector
