"""The architecture you can see in the tree: layers import downward only, and no module
imports itself back through others (imports inside functions count: they are edges too)."""

from __future__ import annotations

import ast
from pathlib import Path
from typing import Dict, List, Set

REPO = Path(__file__).resolve().parents[2]
#: Bottom up; a package may import those of lower rank only.
LAYERS = {"yarp_lite": 0, "nodekit": 1, "walkman": 2, "bridge": 3, "netem": 3, "rosnodes": 4,
          "pilot": 4, "system": 5}


def modules() -> Dict[str, Path]:
    found = {}
    for package in LAYERS:
        for path in (REPO / package).rglob("*.py"):
            parts = path.relative_to(REPO).with_suffix("").parts
            found[".".join(parts[:-1] if parts[-1] == "__init__" else parts)] = path
    return found


def import_graph() -> Dict[str, Set[str]]:
    """Module -> the modules of ours it imports (``from pkg import sub`` is an edge to
    ``pkg.sub``, not to ``pkg``)."""
    known = modules()

    def ours(name: str) -> str:
        while name and name not in known:
            name = name.rpartition(".")[0]
        return name

    graph: Dict[str, Set[str]] = {}
    for name, path in known.items():
        package = name if path.name == "__init__.py" else name.rpartition(".")[0]
        targets: Set[str] = set()
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            if isinstance(node, ast.Import):
                targets.update(ours(alias.name) for alias in node.names)
            elif isinstance(node, ast.ImportFrom):
                base = node.module or ""
                if node.level:
                    anchor = package.split(".")[:len(package.split(".")) - node.level + 1]
                    base = ".".join(anchor + ([base] if base else []))
                for alias in node.names:
                    sub = f"{base}.{alias.name}"
                    targets.add(sub if sub in known else ours(base))
        graph[name] = {target for target in targets if target and target != name}
    return graph


def test_the_import_graph_is_read():
    graph = import_graph()
    assert "yarp_lite.bottle" in graph["yarp_lite.bottle_text"]
    assert "bridge.flows" in graph["bridge.config"]
    assert len(graph) > 150


def test_layers_import_downward_only():
    upward = sorted(f"{source} -> {target}" for source, targets in import_graph().items()
                    for target in targets
                    if LAYERS[target.split(".")[0]] >= LAYERS[source.split(".")[0]]
                    and target.split(".")[0] != source.split(".")[0])
    assert upward == []


#: Inside the bridge, bottom up (bridge/__init__.py): the wire's codecs, the transport that
#: carries them, the GYM policy that uses the transport; the core, the node, its endpoints and
#: the program on top.  Its vocabulary (errors, flows, config, its status) is below them all.
BRIDGE_PARTS = {"wire": 0, "transport": 1, "gym": 2}
BRIDGE_VOCABULARY = {"bridge.errors", "bridge.flows", "bridge.config", "bridge.status"}


def bridge_rank(module: str) -> int:
    parts = module.split(".")
    if module in BRIDGE_VOCABULARY:
        return -1
    if len(parts) > 1 and parts[1] in BRIDGE_PARTS:
        return BRIDGE_PARTS[parts[1]]
    return len(BRIDGE_PARTS)


def test_the_bridges_parts_import_downward_only():
    """The transport knows nothing of the GYM, the wire nothing of either (issue 67)."""
    graph = import_graph()
    bridge = {name for name in graph if name.split(".")[0] == "bridge"}
    assert {"bridge.wire.frames", "bridge.transport.journal", "bridge.gym.delivery",
            "bridge.core"} <= bridge
    upward = sorted(f"{source} -> {target}" for source in bridge for target in graph[source]
                    if target in bridge and bridge_rank(target) > bridge_rank(source))
    assert upward == []


def test_no_module_imports_itself_back():
    graph = import_graph()
    index: Dict[str, int] = {}
    low: Dict[str, int] = {}
    stack: List[str] = []
    cycles: List[List[str]] = []

    def visit(module: str) -> None:          # Tarjan's strongly connected components
        index[module] = low[module] = len(index)
        stack.append(module)
        for target in graph[module]:
            if target not in index:
                visit(target)
                low[module] = min(low[module], low[target])
            elif target in stack:
                low[module] = min(low[module], index[target])
        if low[module] == index[module]:
            component = []
            while True:
                member = stack.pop()
                component.append(member)
                if member == module:
                    break
            if len(component) > 1:
                cycles.append(sorted(component))

    for module in graph:
        if module not in index:
            visit(module)
    assert cycles == []


def test_the_benchmarks_import_nothing_from_the_tests():
    """bench/ runs from an installed tree too: what it shares with the tests lives in the
    packages (walkman.courses, the offline courses), never in tests/."""
    found = []
    for path in sorted((REPO / "bench").glob("*.py")):
        for node in ast.walk(ast.parse(path.read_text(), str(path))):
            names = [alias.name for alias in node.names] if isinstance(node, ast.Import) else \
                [node.module or ""] if isinstance(node, ast.ImportFrom) else []
            found += [f"{path.name}: {name}" for name in names
                      if name == "tests" or name.startswith("tests.")]
    assert found == []
