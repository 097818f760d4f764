"""No module of the package imports, directly or through others, a module that imports it back: lazy imports
inside functions count too (they still tie the two modules)."""

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
    """env/'s sub-packages import each other in one direction only (formulas <- rooms <- engine; view; gymenv on
    top, imported by none of them); a module may import its own package's siblings."""
    edges = import_graph(PACKAGE)
    subs = {p.name for p in (PACKAGE / "env").iterdir() if (p / "__init__.py").is_file()}
    assert {"formulas", "rooms", "engine", "view", "gymenv"} <= subs

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


def package_of(module: str, edges: dict[str, set[str]]) -> str:
    """The package (folder) a module lies in: itself for a package's ``__init__``."""
    return module if any(t.startswith(module + ".") for t in edges) else module.rpartition(".")[0]


def test_the_packages_have_no_import_cycle():
    """Each package (folder) as one node: no cycle between them. env/ and perception/ interleave by layer (docs/
    decisions.md, "Package layers"): env.formulas and env.view sit below perception, whose group estimate the
    engine's observation model runs (env.engine) and whose autoencoders the encoded env wraps (env.gymenv)."""
    edges = import_graph(PACKAGE)
    packages: dict[str, set[str]] = {}
    for m, targets in edges.items():
        a = package_of(m, edges)
        packages.setdefault(a, set()).update(b for b in (package_of(t, edges) for t in targets) if b != a)
        for t in targets:
            packages.setdefault(package_of(t, edges), set())
    assert {"ssbl_pb.perception.tracking", "ssbl_pb.deploy", "ssbl_pb.calib"} <= set(packages)
    assert "ssbl_pb.perception.tracking" in packages["ssbl_pb.env.engine"]  # the observation model
    found = cycles(packages)
    assert found == [], "package cycles: " + "; ".join(" <-> ".join(c) for c in found)
