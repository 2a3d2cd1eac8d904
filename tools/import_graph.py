"""Draw irlsim's import graph as built: the layers of the import-linter layers contract in
``pyproject.toml``, top to bottom, and an arc for every package that imports another
(docs/img/import_graph.svg, shown in docs/design/layers.md).

The graph comes from grimp (installed with import-linter), which reads every import statement, those
inside functions included. An arc from A to B means that some module under A imports some module under B;
it leaves A's box on its right-hand side and ends with an arrowhead at B. The layout is a plain function
of the contract and the edges, written as SVG text, so the file's bytes change only when an import edge
or the contract changes (tests/tools/test_import_graph.py fails when the committed drawing is stale).

Usage: python tools/import_graph.py [--check] [--out PATH]
  (no option)  write docs/img/import_graph.svg
  --check      exit 1, writing nothing, when the file differs from what the code draws now
"""

from __future__ import annotations

import argparse
import sys
import tomllib
from html import escape
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
if str(ROOT) not in sys.path:  # the top-level packages (studies is not installed) import from the checkout
    sys.path.insert(0, str(ROOT))
OUT = ROOT / "docs" / "img" / "import_graph.svg"

ROW = 30  # px between node rows
BOX_W, BOX_H = 200, 22
LEFT, TOP = 36, 70
ARC_STEP = 16  # px of arc bulge per row of distance
PALETTE = ["#1f77b4", "#d62728", "#2ca02c", "#9467bd", "#ff7f0e", "#17becf", "#8c564b", "#e377c2"]


def read_layers(pyproject: Path = ROOT / "pyproject.toml") -> list[list[str]]:
    """The layers contract's layers, top first, each a list of its independent siblings."""
    config = tomllib.loads(pyproject.read_text())["tool"]["importlinter"]
    contract = next(c for c in config["contracts"] if c["type"] == "layers")
    return [[m.strip() for m in layer.split("|")] for layer in contract["layers"]]


def read_edges(nodes: list[str]) -> list[tuple[str, str]]:
    """(importer, imported) pairs between the nodes, in node order; packages count with their modules."""
    import grimp

    roots = sorted({n.split(".")[0] for n in nodes})
    graph = grimp.build_graph(*roots, cache_dir=None)
    return [
        (a, b)
        for a in nodes
        for b in nodes
        if a != b and graph.direct_import_exists(importer=a, imported=b, as_packages=True)
    ]


def render(layers: list[list[str]], edges: list[tuple[str, str]]) -> str:
    """The SVG text: one row per module or package, layers as alternating bands, arcs on the right."""
    nodes = [m for layer in layers for m in layer]
    row = {n: i for i, n in enumerate(nodes)}
    span = max((row[b] - row[a] for a, b in edges), default=1)
    width = max(LEFT + BOX_W + 24 + ARC_STEP * span + 20, 560)
    height = TOP + ROW * len(nodes) + 16
    x_right = LEFT + BOX_W
    out = [
        f'<svg xmlns="http://www.w3.org/2000/svg" width="{width}" height="{height}" '
        f'viewBox="0 0 {width} {height}" font-family="DejaVu Sans, Arial, sans-serif" font-size="12">',
        '<defs><marker id="arrow" viewBox="0 0 8 8" refX="8" refY="4" markerWidth="6" markerHeight="6" '
        'orient="auto-start-reverse"><path d="M 0 0 L 8 4 L 0 8 z" fill="#444"/></marker></defs>',
        f'<rect x="0" y="0" width="{width}" height="{height}" fill="white"/>',
        f'<text x="{LEFT}" y="20" font-size="14" font-weight="bold">irlsim: import graph as built</text>',
        f'<text x="{LEFT}" y="38" fill="#444">layers top to bottom, numbered (pyproject.toml); '
        "siblings of a layer share a band</text>",
        f'<text x="{LEFT}" y="54" fill="#444">an arc A -&gt; B: a module under A imports one under B '
        f"({len(edges)} arcs)</text>",
    ]
    i = 0
    for k, layer in enumerate(layers):
        y0 = TOP + ROW * i - 4
        shade = "#dbe4f0" if k % 2 == 0 else "#f4f6f9"
        out.append(
            f'<rect x="{LEFT - 8}" y="{y0}" width="{BOX_W + 16}" height="{ROW * len(layer)}" fill="{shade}"/>'
        )
        out.append(f'<text x="{LEFT - 30}" y="{y0 + 19}" fill="#444">{k + 1}</text>')
        for name in layer:
            y = TOP + ROW * i
            out.append(
                f'<rect x="{LEFT}" y="{y}" width="{BOX_W}" height="{BOX_H}" rx="4" '
                f'fill="#ffffff" stroke="#333"/>'
            )
            out.append(f'<text x="{LEFT + 8}" y="{y + 15}">{escape(name)}</text>')
            i += 1
    for a, b in edges:
        ia, ib = row[a], row[b]
        ya = TOP + ROW * ia + BOX_H // 2 + 4
        yb = TOP + ROW * ib + BOX_H // 2 - 4
        bulge = x_right + 12 + ARC_STEP * (ib - ia)
        colour = PALETTE[ia % len(PALETTE)]
        out.append(
            f'<path d="M {x_right} {ya} C {bulge} {ya} {bulge} {yb} {x_right + 2} {yb}" fill="none" '
            f'stroke="{colour}" stroke-opacity="0.75" stroke-width="1.2" marker-end="url(#arrow)"/>'
        )
    out.append("</svg>")
    return "\n".join(out) + "\n"


def draw() -> str:
    """The drawing of the code as it is now."""
    layers = read_layers()
    return render(layers, read_edges([m for layer in layers for m in layer]))


def main(argv: list[str] | None = None) -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--check", action="store_true", help="exit 1 when the committed drawing is stale")
    parser.add_argument("--out", type=Path, default=OUT)
    args = parser.parse_args(argv)
    svg = draw()
    if args.check:
        current = args.out.read_text() if args.out.exists() else ""
        if current != svg:
            print(f"{args.out} is stale: run python tools/import_graph.py", file=sys.stderr)
            return 1
        return 0
    args.out.write_text(svg)
    print(f"wrote {args.out}")
    return 0


if __name__ == "__main__":
    sys.exit(main())
