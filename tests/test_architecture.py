"""The layers of docs/architecture.md hold in the code: every import between packages points to a
lower layer, and no module imports itself back through others (a cycle). The imports are read
with `ast` (those inside functions too), so nothing is imported to check them."""
from __future__ import annotations

import ast
import re
from pathlib import Path

REPO = Path(__file__).resolve().parents[1]
ROOTS = ("nicer_stream", "sources", "sinks")


def read_layers(doc: Path = REPO / "docs" / "architecture.md") -> list[list[str]]:
    """The layer block under '## Layers' (the first fenced block there), top layer first; each
    line one layer, its packages separated by spaces; text after '#' is a comment."""
    text = doc.read_text()
    block = re.search(r"## Layers.*?```text\n(.*?)```", text, re.S)
    assert block, f"{doc} has no '## Layers' section with a ```text block"
    layers = [line.split("#")[0].split() for line in block.group(1).splitlines()]
    return [layer for layer in layers if layer]


def module_name(path: Path) -> str:
    parts = list(path.relative_to(REPO).with_suffix("").parts)
    return ".".join(parts[:-1] if parts[-1] == "__init__" else parts)


def package_of(module: str) -> str:
    """'nicer_stream.slam.system' -> 'slam', 'nicer_stream.config' -> 'config', 'sources.tum' -> 'sources'."""
    parts = module.split(".")
    return parts[1] if parts[0] == "nicer_stream" and len(parts) > 1 else parts[0]


def imports_of(path: Path, modules: set[str]) -> set[str]:
    """The project modules `path` imports (relative imports resolved, `from pkg import mod` as mod)."""
    me = module_name(path)
    out = set()
    for node in ast.walk(ast.parse(path.read_text(), str(path))):
        if isinstance(node, ast.Import):
            out |= {a.name for a in node.names}
        elif isinstance(node, ast.ImportFrom):
            base = node.module or ""
            if node.level:
                pkg = me.split(".")[: len(me.split(".")) - node.level + (path.name == "__init__.py")]
                base = ".".join(pkg + ([base] if base else []))
            subs = {f"{base}.{a.name}" for a in node.names} & modules
            out |= subs if len(subs) == len(node.names) else subs | {base}
    return {m for m in out if m in modules and m != me}


def project_graph() -> dict[str, set[str]]:
    files = [p for root in ROOTS for p in (REPO / root).rglob("*.py")]
    modules = {module_name(p) for p in files}
    return {module_name(p): imports_of(p, modules) for p in files}


def upward_arrows(graph: dict[str, set[str]], layers: list[list[str]]) -> list[str]:
    """'a -> b' for each import whose target's package is not in a lower layer than its own (a
    package missing from the layers is reported as well)."""
    rank = {pkg: len(layers) - i for i, layer in enumerate(layers) for pkg in layer}
    bad = []
    for src, targets in sorted(graph.items()):
        for dst in sorted(targets):
            a, b = package_of(src), package_of(dst)
            if a == b:
                continue
            if a not in rank or b not in rank:
                bad.append(f"{src} -> {dst}: package {a if a not in rank else b} is in no layer")
            elif rank[b] >= rank[a]:
                bad.append(f"{src} -> {dst}: {a} may not import {b}")
    return bad


def cycles(graph: dict[str, set[str]]) -> list[list[str]]:
    """The strongly connected components with more than one module (Tarjan)."""
    index, low, stack, on, out = {}, {}, [], set(), []

    def visit(v: str) -> None:
        index[v] = low[v] = len(index)
        stack.append(v)
        on.add(v)
        for w in graph.get(v, ()):
            if w not in index:
                visit(w)
                low[v] = min(low[v], low[w])
            elif w in on:
                low[v] = min(low[v], index[w])
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

    for v in sorted(graph):
        if v not in index:
            visit(v)
    return out


def test_imports_point_down_the_layers_of_docs_architecture():
    bad = upward_arrows(project_graph(), read_layers())
    assert not bad, "imports against docs/architecture.md's layers:\n" + "\n".join(bad)


def test_no_import_cycle():
    assert not cycles(project_graph())


def test_every_package_is_in_exactly_one_layer():
    layers = read_layers()
    listed = [pkg for layer in layers for pkg in layer]
    assert len(listed) == len(set(listed)), "a package listed twice"
    found = {package_of(m) for m in project_graph()} - {"nicer_stream"}
    assert found <= set(listed), f"not in docs/architecture.md's layers: {sorted(found - set(listed))}"


def test_the_checks_catch_an_upward_arrow_a_sideways_arrow_and_a_cycle():
    layers = [["slam"], ["frontend", "tracking"], ["geometry"]]
    assert upward_arrows({"nicer_stream.slam.a": {"nicer_stream.geometry.b"}}, layers) == []
    assert upward_arrows({"nicer_stream.geometry.b": {"nicer_stream.slam.a"}}, layers) == [
        "nicer_stream.geometry.b -> nicer_stream.slam.a: geometry may not import slam"]
    assert len(upward_arrows({"nicer_stream.frontend.f": {"nicer_stream.tracking.t"}}, layers)) == 1
    assert cycles({"a": {"b"}, "b": {"c"}, "c": {"a"}, "d": {"a"}}) == [["a", "b", "c"]]
    assert cycles({"a": {"b"}, "b": set()}) == []
