"""The report's "Pipeline and DAG overview" section: Snakemake's own rule graph of this run,
drawn with each rule's job count (report/dag.py parses and draws it)."""

from __future__ import annotations

from collections.abc import Mapping

import networkx as nx

from graspstab.report import dag
from graspstab.report import html as H


def pipeline_parts(
    graph: nx.DiGraph | None, counts: Mapping[str, int] | None, dpi: int
) -> list[str]:
    """The DAG overview: Snakemake's rule graph drawn with each rule's job count."""
    head = H.heading(2, "pipeline", "Pipeline and DAG overview")
    if graph is None or counts is None:
        return [head, '<p class="note">No rule graph given to the report.</p>']
    return [
        head,
        f"<p>{H.esc(dag.overview_text(graph, counts))}</p>",
        H.image(
            dag.draw_rule_graph(graph, counts, dpi),
            "rule graph",
            "Rule graph of this run (snakemake --rulegraph), top to bottom, with each rule's job "
            "count (snakemake --dag); orange: rules that fan out into several jobs. Edges implied "
            "by a longer path are omitted.",
            "rule-graph",
        ),
    ]
