"""No module of the package imports, directly or through others, a module that imports it back, and no top-level
package imports a layer above its own: lazy imports inside functions count too (they still tie the two modules)."""

from __future__ import annotations

import ast
from pathlib import Path

PACKAGE = Path(__file__).resolve().parents[1] / "ssbl_pb"


def import_graph(package: Path) -> dict[str, set[str]]:
    """Module name -> the package's modules it imports (``from x import y`` counts module ``x.y`` when it is one)."""
    mods = {}
    for f in package.rglob("*.py"):
        rel = f.relative_to(package.parent).with_suffix("")
        mods[".".join(rel.parts[:-1] if rel.name == "__init__" else rel.parts)] = f
    edges: dict[str, set[str]] = {m: set() for m in mods}
    for m, f in mods.items():
        here = m.split(".") if f.name == "__init__.py" else m.split(".")[:-1]
        for node in ast.walk(ast.parse(f.read_text())):
            if isinstance(node, ast.Import):
                targets = [a.name for a in node.names]
            elif isinstance(node, ast.ImportFrom):
                base = ".".join(here[:len(here) - node.level + 1] + [node.module or ""]).strip(".") if node.level \
                    else node.module or ""
                targets = [base] + [f"{base}.{a.name}" for a in node.names]
            else:
                continue
            for t in targets:
                while t and t not in mods:
                    t = t.rpartition(".")[0]
                if t and t != m and t != package.name:
                    edges[m].add(t)
    return edges


def cycles(edges: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components of more than one module (Tarjan's algorithm, iterative)."""
    index: dict[str, int] = {}
    low: dict[str, int] = {}
    stack: list[str] = []
    on: set[str] = set()
    out = []
    for root in edges:
        if root in index:
            continue
        work = [(root, iter(sorted(edges[root])))]
        index[root] = low[root] = len(index)
        stack.append(root)
        on.add(root)
        while work:
            v, it = work[-1]
            w = next(it, None)
            if w is not None:
                if w not in index:
                    index[w] = low[w] = len(index)
                    stack.append(w)
                    on.add(w)
                    work.append((w, iter(sorted(edges[w]))))
                elif w in on:
                    low[v] = min(low[v], index[w])
                continue
            work.pop()
            if work:
                low[work[-1][0]] = min(low[work[-1][0]], low[v])
            if low[v] == index[v]:
                comp = []
                while True:
                    w = stack.pop()
                    on.discard(w)
                    comp.append(w)
                    if w == v:
                        break
                if len(comp) > 1:
                    out.append(sorted(comp))
    return out


def test_the_finder_finds_a_cycle_and_only_cycles():
    edges = {"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}, "e": set()}
    assert cycles(edges) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []


def test_the_package_has_no_import_cycle():
    edges = import_graph(PACKAGE)
    assert len(edges) > 100 and "ssbl_pb.env.engine.batched" in edges["ssbl_pb.env.gymenv.approach"]
    assert cycles(edges) == [], "import cycles: " + "; ".join(" <-> ".join(c) for c in cycles(edges))


def test_the_env_sub_packages_are_layered():
    """env/'s sub-packages import each other in one direction only (rooms <- engine; view; gymenv on top, imported
    by none of them); a module may import its own package's siblings."""
    edges = import_graph(PACKAGE)
    subs = {p.name for p in (PACKAGE / "env").iterdir() if (p / "__init__.py").is_file()}
    assert {"rooms", "engine", "view", "gymenv"} <= subs

    def sub(m):
        parts = m.split(".")
        return parts[2] if len(parts) > 3 and parts[:2] == ["ssbl_pb", "env"] and parts[2] in subs else None

    packages: dict[str, set[str]] = {s: set() for s in subs}
    for m, targets in edges.items():
        for t in targets:
            if sub(m) and sub(t) and sub(m) != sub(t):
                packages[sub(m)].add(sub(t))
    assert cycles(packages) == [], packages
    assert "gymenv" not in set().union(*packages.values())


# The package's layers, bottom up: a package imports only from its own layer and those below (docs: README, "Layers").
# The base holds the root modules and data packages every layer may use.
BASE = ("ssbl_pb", "params", "errors", "files", "cli", "urdf", "policies", "data")  # ssbl_pb: its __init__
LAYERS = (("core",), ("perception",), ("env",), ("agents",), ("training", "calib", "deploy"), ("virtual",),
          ("analysis", "sweep", "bench"))


def top_level_graph(edges: dict[str, set[str]]) -> dict[str, set[str]]:
    """Top-level package (or root module) -> those it imports, lazy imports included."""
    def top(m: str) -> str:
        parts = m.split(".")
        return parts[1] if len(parts) > 1 else parts[0]

    graph: dict[str, set[str]] = {}
    for m, targets in edges.items():
        graph.setdefault(top(m), set()).update(top(t) for t in targets if top(t) != top(m))
    return graph


def test_the_top_level_packages_have_no_import_cycle():
    graph = top_level_graph(import_graph(PACKAGE))
    assert {"core", "perception", "env", "agents", "deploy", "bench"} <= set(graph)
    found = cycles(graph)
    assert len(found) == 0, "top-level package cycles: " + "; ".join(" <-> ".join(c) for c in found)


def test_no_package_imports_a_layer_above_its_own():
    graph = top_level_graph(import_graph(PACKAGE))
    layer = {name: k + 1 for k, names in enumerate(LAYERS) for name in names} | {name: 0 for name in BASE}
    assert set(graph) <= set(layer), f"packages in no layer: {sorted(set(graph) - set(layer))}"
    upward = sorted(f"{a} -> {b}" for a, targets in graph.items() for b in targets if layer[b] > layer[a])
    assert upward == [], upward


def test_the_readme_draws_these_layers():
    """The README's one-line layer order names the same layers, bottom up."""
    text = (PACKAGE.parent / "README.md").read_text()
    line = next(ln for ln in text.splitlines() if ln.strip().startswith("core <"))
    drawn = tuple(tuple(n.strip(" `") for n in part.split(",")) for part in line.strip().split("<"))
    assert drawn[:-1] == LAYERS and drawn[-1] == ("tools",), drawn
