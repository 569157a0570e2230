"""The pipeline overview: Snakemake's own rule graph and job graph (dot text) parsed into networkx
and drawn with matplotlib, so the figure cannot drift from the workflow (no graphviz binary needed).

The dot files come from rule ``rulegraph`` (workflow/rules/report.smk), which runs
``snakemake --rulegraph`` and ``snakemake --dag`` on the run's own configuration.
"""

from __future__ import annotations

import io
import re
from collections import Counter
from collections.abc import Mapping
from pathlib import Path

import networkx as nx

from graspstab.common.plotting import plt, save

# Half a rule box's height in row units (rows are 0.8 in apart, a box about 0.4 in tall).
BOX_HALF_HEIGHT = 0.3
_NODE = re.compile(r'^\s*(\w+)\s*\[\s*label\s*=\s*"((?:[^"\\]|\\.)*)"', re.M)
_EDGE = re.compile(r"^\s*(\w+)\s*->\s*(\w+)", re.M)


def parse_dot(text: str) -> tuple[dict[str, str], list[tuple[str, str]]]:
    """Node id -> rule name, and the edges (ids), of a Snakemake ``--rulegraph``/``--dag`` dot
    text; a job node's label is its rule name, then its wildcards after a ``\\n``."""
    nodes = {m[1]: m[2].split("\\n")[0].strip() for m in _NODE.finditer(text)}
    edges = [(m[1], m[2]) for m in _EDGE.finditer(text)]
    unknown = {n for e in edges for n in e} - set(nodes)
    if unknown:
        raise ValueError(f"dot text has edges from/to undeclared nodes {sorted(unknown)}")
    return nodes, edges


def rule_graph(text: str) -> nx.DiGraph:
    """The rule-level graph (edge = a rule's output feeds another rule) of a dot text; works for
    both ``--rulegraph`` and the job-level ``--dag`` (jobs are collapsed onto their rules)."""
    nodes, edges = parse_dot(text)
    graph = nx.DiGraph()
    graph.add_nodes_from(sorted(set(nodes.values())))
    graph.add_edges_from((nodes[a], nodes[b]) for a, b in edges if nodes[a] != nodes[b])
    return graph


def job_counts(text: str) -> Counter[str]:
    """Jobs per rule in a job-level ``--dag`` dot text."""
    return Counter(parse_dot(text)[0].values())


def layers(graph: nx.DiGraph) -> dict[str, int]:
    """Each rule's depth: the longest path from a source rule to it (rows of the drawing)."""
    return {n: r for r, gen in enumerate(nx.topological_generations(graph)) for n in gen}


def _with_dummies(graph: nx.DiGraph, depth: Mapping[str, int]) -> tuple[nx.DiGraph, dict]:
    """The graph with every edge that skips rows split into one-row hops through dummy nodes
    (tuples), the usual trick so that long edges are routed between boxes, not through them."""
    out = nx.DiGraph()
    out.add_nodes_from(graph.nodes)
    rank = dict(depth)
    for a, b in graph.edges:
        prev = a
        for r in range(depth[a] + 1, depth[b]):
            dummy = (a, b, r)
            rank[dummy] = r
            out.add_edge(prev, dummy)
            prev = dummy
        out.add_edge(prev, b)
    return out, rank


def _ordered_rows(graph: nx.DiGraph, rank: Mapping) -> list[list]:
    """Nodes per row, ordered by a few barycentre sweeps so that edges cross less."""
    rows: list[list] = [[] for _ in range(max(rank.values(), default=-1) + 1)]
    for node in nx.topological_sort(graph):
        rows[rank[node]].append(node)
    for _ in range(6):
        for sweep, neighbours in ((rows[1:], graph.predecessors), (rows[-2::-1], graph.successors)):
            pos = {n: i / max(len(r), 1) for r in rows for i, n in enumerate(r)}
            for row in sweep:
                row.sort(key=lambda n: _mean([pos[m] for m in neighbours(n)], pos[n]))
    return rows


def _mean(values: list[float], default: float) -> float:
    return sum(values) / len(values) if values else default


def _half(node: object) -> float:
    return 0.5 if isinstance(node, str) else 0.1


def _positions(graph: nx.DiGraph, rows: list[list]) -> tuple[dict, float]:
    """x, y of every node: rows top to bottom, a rule one unit wide, a dummy a fifth of one;
    then each dummy slides towards its neighbours' mean x (kept between the row's neighbours),
    which straightens long edges without letting them cross a box."""
    span = max((sum(2 * _half(n) for n in row) for row in rows), default=1.0)
    pos = {}
    for r, row in enumerate(rows):
        x = (span - sum(2 * _half(n) for n in row)) / 2
        for n in row:
            pos[n] = [x + _half(n), -r]
            x += 2 * _half(n)
    for _ in range(20):
        for row in rows:
            for i, n in enumerate(row):
                if isinstance(n, str):
                    continue
                near = [*graph.predecessors(n), *graph.successors(n)]
                lo = pos[row[i - 1]][0] + _half(row[i - 1]) + 0.1 if i else -1e9
                hi = pos[row[i + 1]][0] - _half(row[i + 1]) - 0.1 if i + 1 < len(row) else 1e9
                target = sum(pos[m][0] for m in near) / len(near)
                pos[n][0] = min(max(target, lo), hi) if lo <= hi else (lo + hi) / 2
    return {n: (x, y) for n, (x, y) in pos.items()}, span


def draw_rule_graph(graph: nx.DiGraph, counts: Mapping[str, int], dpi: int = 110) -> bytes:
    """A PNG of the rule graph, one box per rule with its job count, top to bottom. Edges implied
    by a longer path are left out (transitive reduction): the report rule reads almost every
    artefact directly, which would otherwise hide the pipeline's order under a fan of arrows."""
    shown = nx.transitive_reduction(graph) if nx.is_directed_acyclic_graph(graph) else graph
    routed, rank = _with_dummies(shown, layers(shown))
    rows = _ordered_rows(routed, rank)
    pos, span = _positions(routed, rows)
    fig, ax = plt.subplots(figsize=(max(9.0, 1.55 * span), 0.8 * len(rows) + 0.6))

    def end(node: object, side: float) -> tuple[float, float]:
        """Where an edge meets a node: a box's top or bottom edge, a dummy's centre."""
        x, y = pos[node]
        return (x, y + side * BOX_HALF_HEIGHT) if isinstance(node, str) else (x, y)

    for a, b in routed.edges:
        if isinstance(b, str):  # the last hop carries the arrow head
            ax.annotate("", xy=end(b, 1), xytext=end(a, -1), zorder=1, arrowprops={
                "arrowstyle": "-|>", "color": "0.55", "lw": 1.0, "shrinkA": 0, "shrinkB": 0})
        else:
            ax.plot(*zip(end(a, -1), end(b, 1), strict=True), color="0.55", lw=1.0, zorder=1)
    for node in graph.nodes:
        x, y = pos[node]
        n = int(counts.get(node, 0))
        fan = n > 1
        ax.text(
            x, y, f"{node}\n{n} job{'s' if n != 1 else ''}" if n else f"{node}\njobs: ?",
            ha="center", va="center", fontsize=8.5, zorder=3,
            bbox={"boxstyle": "round,pad=0.35", "fc": "#fde7c8" if fan else "#dcebf7",
                  "ec": "#c77800" if fan else "#2b6a99", "lw": 1.0},
        )  # fmt: skip
    ax.set_xlim(-0.1, span + 0.1)
    ax.set_ylim(-len(rows) + 0.5, 0.5)
    ax.axis("off")
    fig.tight_layout()
    buf = io.BytesIO()
    save(fig, buf, dpi, tight=True)
    return buf.getvalue()


def overview_text(graph: nx.DiGraph, counts: Mapping[str, int]) -> str:
    """One plain-text paragraph on the DAG: its size, its longest chain and where it fans out."""
    total = sum(counts.values())
    chain = nx.dag_longest_path(graph) if nx.is_directed_acyclic_graph(graph) else []
    fans = sorted(((c, r) for r, c in counts.items() if c > 1), reverse=True)
    fan_text = ", ".join(f"{r} ({c})" for c, r in fans) or "none"
    return (
        f"The workflow runs {graph.number_of_nodes()} rules as {total} jobs for this "
        f"configuration. Its longest chain of dependent rules has {len(chain)} steps "
        f"({' → '.join(chain)}). Rules that fan out over objects, shards, windows, models, "
        f"seeds or split assignments (jobs): {fan_text}; the rest run once. The graph is "
        "Snakemake's own (--rulegraph, with job counts from --dag), made at run time by rule "
        "rulegraph, so it is the DAG this report came from rather than a drawing of it."
    )


def read_graph(rulegraph: Path, jobgraph: Path) -> tuple[nx.DiGraph, Counter[str]]:
    """The rule graph and jobs per rule from the two dot files of rule ``rulegraph``."""
    graph = rule_graph(Path(rulegraph).read_text())
    counts = job_counts(Path(jobgraph).read_text())
    return graph, counts
