"""Study report: verdicts, Pareto figure, failure causes, then the detailed tables.

``write_study_report(DIR)`` reads ``DIR/study.json`` and the Parquet dataset and writes
``DIR/study_report.md``, ``DIR/study_report.html`` (the run report's style, figures embedded)
and ``DIR/figures/*.png``.

Per robot the report leads with the verdict in plain words — which controller to pick for
singular crossings, for tasks certified unachievable, for undecided ones (the reference's
bracket labels) and for limit-bound motion, each backed by the
exact McNemar test on the same tasks, and the most accurate one by the Wilcoxon test of the
oracle-relative error — and a Pareto figure, then the failure causes per controller and
generator, the worst episode of each controller (with its id for ``otmm-qp study show``) and
the detailed tables. Rows with ``controller == "oracle"`` are the task's offline reference:
shown as a row and a point, never ranked or tested; their ``reference.*`` columns (joined by
``task_id``) give every controller row its **oracle-relative error**
``max_error − reference.max_error`` [m].

The package only renders (optuna's ``visualization/`` shape): the verdicts, tests, fronts and
summaries are typed results of :mod:`otmm_qp.studies.verdicts` and its neighbours, the data
model is :mod:`otmm_qp.studies.rows`. One module per concern:

- :mod:`.compose` — the document and :func:`write_study_report`;
- :mod:`.tables` — the tables (:class:`~otmm_qp.studies.document.Table` items);
- :mod:`.lines` — the plain-words verdict and ranking lines;
- :mod:`.figures` — the matplotlib figures;
- :mod:`.html` — the HTML page.
"""

from __future__ import annotations

from otmm_qp.studies.report.compose import document, render_markdown, write_study_report

__all__ = ["document", "render_markdown", "write_study_report"]
