"""The table model of :mod:`anigs.reports.tables` (:class:`Cell`, :class:`Table` with numbered n/a
footnotes) and its renderings: CSV, Markdown and LaTeX."""
from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from typing import Any

MISSING = "no metrics file for this scene/method/variant"


@dataclass
class Cell:
    value: float | None = None
    note: int | None = None  # footnote number when n/a
    bold: bool = False
    fmt: str = "{:.2f}"
    suffix: str = ""  # printed after the value (e.g. a spread and a sample count)

    def text(self) -> str:
        if self.value is None:
            return "n/a"
        if isinstance(self.value, float) and math.isinf(self.value):
            return "inf"
        return self.fmt.format(self.value) + self.suffix


@dataclass
class Table:
    name: str
    title: str
    header: list[str]
    rows: list[tuple[str, list[Cell]]] = field(default_factory=list)  # (label, cells); label '' + no cells = rule
    sections: dict[int, str] = field(default_factory=dict)  # row index -> section heading before it
    footnotes: list[str] = field(default_factory=list)

    def note(self, reason: str) -> int:
        if reason not in self.footnotes:
            self.footnotes.append(reason)
        return self.footnotes.index(reason) + 1

    def cell(self, metric: dict[str, Any] | None, missing_reason: str = MISSING, fmt: str = "{:.2f}") -> Cell:
        if metric is None:
            return Cell(None, self.note(missing_reason), fmt=fmt)
        if not metric.get("available", metric.get("value") is not None) or metric.get("value") is None:
            return Cell(None, self.note(metric.get("reason") or "not available"), fmt=fmt)
        v = metric["value"]
        return Cell(float(v), fmt=fmt)  # float("inf") also reads the "inf" that write_json stores


def _split_label(t: Table, label: str) -> list[str]:
    return label.split(" | ") if t.name in ("weightfree", "fvd_gt") else [label]


def to_csv(t: Table) -> str:
    """CSV; tables with sections (prior blocks) get a leading ``block`` column; footnotes as ``# [i]`` rows."""
    buf = io.StringIO()
    w = csv.writer(buf, lineterminator="\n")
    w.writerow((["block"] if t.sections else []) + t.header)
    section = ""
    for i, (label, cells) in enumerate(t.rows):
        section = t.sections.get(i, section)
        w.writerow(([section] if t.sections else []) + _split_label(t, label)
                   + [c.text() if c.note is None else f"n/a [{c.note}]" for c in cells])
    for i, note in enumerate(t.footnotes, 1):
        w.writerow([f"# [{i}] {note}"])
    return buf.getvalue()


def _n_label_cols(t: Table) -> int:
    return len(t.header) - (len(t.rows[0][1]) if t.rows else len(t.header) - 1)


def _md_escape(s: str) -> str:
    return s.replace("|", "\\|")


def to_markdown(t: Table) -> str:
    lines = [f"**{t.title}**", "", "| " + " | ".join(_md_escape(h) for h in t.header) + " |",
             "|" + "|".join([":--"] * _n_label_cols(t) + ["--:"] * (len(t.header) - _n_label_cols(t))) + "|"]
    width = len(t.header)
    for i, (label, cells) in enumerate(t.rows):
        if i in t.sections:
            lines.append("| " + " | ".join([f"**{_md_escape(t.sections[i])}**"] + [""] * (width - 1)) + " |")
        texts = []
        for c in cells:
            s = c.text() if c.note is None else f"n/a<sup>{c.note}</sup>"
            texts.append(f"**{s}**" if c.bold else s)
        lines.append("| " + " | ".join([_md_escape(x) for x in _split_label(t, label)] + texts) + " |")
    if t.footnotes:
        lines.append("")
        lines += [f"<sup>{i}</sup> {_md_escape(n)}  " for i, n in enumerate(t.footnotes, 1)]
    return "\n".join(lines) + "\n"


def _tex_escape(s: str) -> str:
    out = s
    for a, b in (("\\", r"\textbackslash{}"), ("&", r"\&"), ("%", r"\%"), ("$", r"\$"), ("#", r"\#"),
                 ("_", r"\_"), ("{", r"\{"), ("}", r"\}"), ("~", r"\textasciitilde{}"), ("^", r"\^{}")):
        out = out.replace(a, b) if a != "\\" else out.replace(a, "\x00")
    out = out.replace("\x00", r"\textbackslash{}")
    return out.replace("ComposedV2V", r"\textsc{ComposedV2V}")


def to_latex(t: Table) -> str:
    ncols = len(t.header)
    nvals = ncols - _n_label_cols(t)
    lines = [r"\begin{table}[t]", r"\centering", r"\caption{" + _tex_escape(t.title) + "}",
             r"\label{tab:" + t.name + "}", r"\footnotesize",
             r"\begin{tabular}{" + "l" * (ncols - nvals) + "c" * nvals + "}",
             r"\toprule", " & ".join(_tex_escape(h) for h in t.header) + r" \\", r"\midrule"]
    for i, (label, cells) in enumerate(t.rows):
        if i in t.sections:
            if i:
                lines.append(r"\midrule")
            lines.append(r"\textbf{" + _tex_escape(t.sections[i]) + r"} \\")
            lines.append(r"\midrule")
        texts = []
        for c in cells:
            s = c.text() if c.note is None else f"n/a$^{{{c.note}}}$"
            texts.append(r"\textbf{" + s + "}" if c.bold else s)
        lines.append(" & ".join([_tex_escape(x) for x in _split_label(t, label)] + texts) + r" \\")
    lines += [r"\bottomrule", r"\end{tabular}"]
    if t.footnotes:
        lines.append(r"\par\smallskip{\scriptsize " + " ".join(f"$^{{{i}}}$ {_tex_escape(n)}."
                                                                for i, n in enumerate(t.footnotes, 1)) + "}")
    lines.append(r"\end{table}")
    return "\n".join(lines) + "\n"
