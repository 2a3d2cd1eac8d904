"""The committed import-graph drawing (docs/img/import_graph.svg, docs/design/layers.md) is the one the
code draws now: adding or removing an import edge between irlsim's layers, or changing the layers contract,
without running ``python tools/import_graph.py`` fails here."""

from __future__ import annotations

import importlib.util
from pathlib import Path

ROOT = Path(__file__).resolve().parents[2]


def _tool():
    spec = importlib.util.spec_from_file_location("import_graph", ROOT / "tools" / "import_graph.py")
    assert spec is not None and spec.loader is not None
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_committed_drawing_is_current():
    tool = _tool()
    assert (ROOT / "docs" / "img" / "import_graph.svg").read_text() == tool.draw(), (
        "docs/img/import_graph.svg is stale: run `python tools/import_graph.py` (or `make import-graph`)"
    )


def test_drawing_follows_the_layers_contract():
    tool = _tool()
    layers = tool.read_layers()
    nodes = [m for layer in layers for m in layer]
    rank = {m: k for k, layer in enumerate(layers) for m in layer}
    edges = tool.read_edges(nodes)
    assert edges, "grimp found no import edge"
    assert all(rank[a] < rank[b] for a, b in edges), "an edge points up or sideways"
    svg = tool.render(layers, edges)
    assert svg == tool.render(layers, list(edges)), "the drawing is not a function of its input"
    assert svg.count("marker-end") == len(edges)
    assert all(f">{m}</text>" in svg for m in nodes)
