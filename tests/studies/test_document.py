"""The report's document model: one list of items, rendered to Markdown and to HTML."""

from __future__ import annotations

from otmm_qp.studies.document import Figure, Heading, to_html, to_markdown

ITEMS = [
    Heading(1, "Study <x>"),
    "",
    "A description with <b>.",
    "",
    Heading(3, "Verdict", box=True),
    "",
    "- **Singular crossings**: pick **a**.",
    "",
    Figure("figures/p.png", "Pareto: r"),
    "",
    Heading(3, "Table"),
    "",
    "| a | b |",
    "|---|---|",
    "| 1 | 2 |",
    "",
]


def test_markdown_is_one_line_per_item() -> None:
    text = to_markdown(ITEMS)
    assert text.splitlines()[0] == "# Study <x>"
    assert "### Verdict" in text and "![Pareto: r](figures/p.png)" in text
    assert len(text.split("\n")) == len(ITEMS)


def test_html_knows_headings_boxes_and_figures_by_their_type() -> None:
    shown: list[Figure] = []

    def figure(item: Figure) -> str:
        shown.append(item)
        return f"<figure>{item.caption}</figure>"

    page = to_html(ITEMS, "Study <x>", "body{}", figure)
    assert page.startswith("<!DOCTYPE html>") and page.endswith("</body></html>\n")
    assert "<title>Study &lt;x&gt;</title>" in page and "<h3>Study &lt;x&gt;</h3>" in page
    assert "<p>A description with &lt;b&gt;.</p>" in page
    assert '<div class="verdict"><h5>Verdict</h5></div>' in page
    assert '<div class="verdict"><ul><li><strong>Singular crossings</strong>' in page
    assert shown == [Figure("figures/p.png", "Pareto: r")]
    table = page.index("<h5>Table</h5>")
    assert '<div class="verdict">' not in page[table:]  # the box ends at the next heading
    assert "<table><tr><th>a</th><th>b</th><tr><td>1</td><td>2</td></table>" in page
