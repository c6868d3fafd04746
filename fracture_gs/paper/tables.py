"""A table model written as Markdown, CSV and LaTeX (booktabs) from one definition."""

from __future__ import annotations

import csv
import io
import math
from dataclasses import dataclass, field
from pathlib import Path
from typing import Optional

# --------------------------------------------------------------------------------------------
# tables: Markdown, CSV, LaTeX


@dataclass
class Column:
    key: str
    md: str  # Markdown header
    tex: str  # LaTeX header
    kind: str = "num"  # num | sci | int | text | bool | pair | meanmax | time


@dataclass
class Panel:
    columns: list
    rows: list  # list of dicts key -> raw value
    title: Optional[str] = None


@dataclass
class Table:
    key: str  # file stem, e.g. table1_transfer
    title: str
    panels: list
    caption: str
    label: str = ""
    command: str = ""
    bold: dict = field(default_factory=dict)  # (panel index, row index, column key) -> True

    # ---- formatting ---------------------------------------------------------------------------
    @staticmethod
    def _num_md(v: float, kind: str) -> str:
        if v is None or (isinstance(v, float) and not math.isfinite(v)):
            return "—" if v is None else str(v)
        v = float(v)
        if v == 0:
            return "0"
        if kind == "sci" or abs(v) < 1e-3 or abs(v) >= 1e5:
            return f"{v:.3e}"
        return f"{v:.3f}"

    @staticmethod
    def _num_tex(v: float, kind: str) -> str:
        if v is None:
            return "--"
        v = float(v)
        if not math.isfinite(v):
            return r"\text{nan}" if v != v else (r"\infty" if v > 0 else r"-\infty")
        if v == 0:
            return "0"
        if kind == "sci" or abs(v) < 1e-3 or abs(v) >= 1e5:
            m, e = f"{v:.3e}".split("e")
            return f"{m}{{\\times}}10^{{{int(e)}}}"
        return f"{v:.3f}"

    @classmethod
    def cell(cls, v, kind: str, fmt: str) -> str:
        """One cell as Markdown (`fmt="md"`) or LaTeX (`fmt="tex"`)."""
        tex = fmt == "tex"
        if v is None:
            return "--" if tex else "—"
        if kind == "bool":
            return "Yes" if v else "No"
        if kind == "text":
            return tex_escape(str(v)) if tex else str(v)
        if kind == "int":
            return str(int(v))
        if kind in ("pair", "meanmax"):
            parts = [cls.cell(a, "num" if kind == "pair" else "sci_auto", fmt) for a in v]
            s = "/".join(p.strip("$") for p in parts)
            return f"${s}$" if tex else s
        if kind == "time_pair":
            parts = (
                ["--" if a is None else f"{float(a):.3f}" for a in v]
                if tex
                else ["—" if a is None else f"{float(a):.3f}" for a in v]
            )
            return "/".join(parts)
        k = "num" if kind == "sci_auto" else kind
        return f"${cls._num_tex(v, k)}$" if tex else cls._num_md(v, k)

    def markdown(self) -> str:
        lines = [f"### {self.title}", ""]
        for pi, p in enumerate(self.panels):
            if p.title:
                lines += [f"*{p.title}*", ""]
            lines.append("| " + " | ".join(c.md for c in p.columns) + " |")
            lines.append("|" + "|".join(":---" if c.kind == "text" else "---:" for c in p.columns) + "|")
            for ri, r in enumerate(p.rows):
                cells = []
                for c in p.columns:
                    s = self.cell(r.get(c.key), c.kind, "md")
                    cells.append(f"**{s}**" if self.bold.get((pi, ri, c.key)) else s)
                lines.append("| " + " | ".join(cells) + " |")
            lines.append("")
        lines.append(self.caption)
        if self.command:
            lines += ["", f"Command: `{self.command}`"]
        return "\n".join(lines) + "\n"

    def latex(self) -> str:
        ncol = max(len(p.columns) for p in self.panels)
        spec = "l" * min(2, ncol) + "c" * (ncol - min(2, ncol))
        out = [r"\begin{table*}[t]", r"\centering", r"\small", f"\\begin{{tabular}}{{{spec}}}", r"\toprule"]
        for pi, p in enumerate(self.panels):
            if pi:
                out.append(r"\midrule")
            if p.title:
                out += [f"\\multicolumn{{{ncol}}}{{l}}{{\\textit{{{tex_escape(p.title)}}}}} \\\\", r"\midrule"]
            heads = [c.tex for c in p.columns] + [""] * (ncol - len(p.columns))
            out += [" & ".join(heads) + r" \\", r"\midrule"]
            for ri, r in enumerate(p.rows):
                cells = []
                for c in p.columns:
                    s = self.cell(r.get(c.key), c.kind, "tex")
                    if self.bold.get((pi, ri, c.key)):
                        s = f"$\\mathbf{{{s.strip('$')}}}$" if s.startswith("$") else f"\\textbf{{{s}}}"
                    cells.append(s)
                cells += [""] * (ncol - len(cells))
                out.append(" & ".join(cells) + r" \\")
        out += [r"\bottomrule", r"\end{tabular}", f"\\caption{{{tex_escape(self.caption, math_ok=True)}}}"]
        if self.label:
            out.append(f"\\label{{{self.label}}}")
        out.append(r"\end{table*}")
        return "\n".join(out) + "\n"

    def csv_texts(self) -> dict:
        """{suffix: CSV text}: one CSV per panel ('' for a single panel, '_A', '_B', ... otherwise);
        raw values at full precision, mean/max pairs split into two columns."""
        texts = {}
        for pi, p in enumerate(self.panels):
            buf = io.StringIO()
            w = csv.writer(buf, lineterminator="\n")
            head = []
            for c in p.columns:
                if c.kind in ("pair", "meanmax", "time_pair"):
                    head += [
                        f"{c.key}_0" if c.kind != "meanmax" else f"{c.key}_mean",
                        f"{c.key}_1" if c.kind != "meanmax" else f"{c.key}_max",
                    ]
                else:
                    head.append(c.key)
            w.writerow(head)
            for r in p.rows:
                vals = []
                for c in p.columns:
                    v = r.get(c.key)
                    if c.kind in ("pair", "meanmax", "time_pair"):
                        vals += [
                            ""
                            if v is None or v[0] is None
                            else repr(float(v[0]))
                            if not isinstance(v[0], str)
                            else v[0],
                            ""
                            if v is None or v[1] is None
                            else repr(float(v[1]))
                            if not isinstance(v[1], str)
                            else v[1],
                        ]
                    elif v is None:
                        vals.append("")
                    elif isinstance(v, bool):
                        vals.append("yes" if v else "no")
                    elif isinstance(v, float):
                        vals.append(repr(v))
                    else:
                        vals.append(str(v))
                w.writerow(vals)
            texts["" if len(self.panels) == 1 else "_" + chr(ord("A") + pi)] = buf.getvalue()
        return texts

    def write(self, folder) -> list:
        """Write KEY.md, KEY.tex and KEY[_A|_B].csv into folder; returns the paths."""
        folder = Path(folder)
        folder.mkdir(parents=True, exist_ok=True)
        paths = [folder / f"{self.key}.md", folder / f"{self.key}.tex"]
        paths[0].write_text(self.markdown())
        paths[1].write_text(self.latex())
        for suffix, text in self.csv_texts().items():
            p = folder / f"{self.key}{suffix}.csv"
            p.write_text(text)
            paths.append(p)
        return paths


_TEX_SPECIAL = {
    "&": r"\&",
    "%": r"\%",
    "#": r"\#",
    "_": r"\_",
    "{": r"\{",
    "}": r"\}",
    "~": r"\textasciitilde{}",
    "^": r"\textasciicircum{}",
    "\\": r"\textbackslash{}",
}
_TEX_UNICODE = {
    "Δ": r"$\Delta$",
    "×": r"$\times$",
    "–": "--",
    "—": "---",
    "≥": r"$\geq$",
    "≤": r"$\leq$",
    "σ": r"$\sigma$",
    "ρ": r"$\rho$",
    "·": r"$\cdot$",
    "³": r"$^3$",
    "≈": r"$\approx$",
    "→": r"$\to$",
    "µ": r"$\mu$",
    "‖": r"$\|$",
    "⁰": r"$^0$",
    "¹": r"$^1$",
}


def tex_escape(text: str, math_ok: bool = False) -> str:
    """Escape LaTeX specials; `math_ok` keeps $...$ spans (and their backslashes) as they are."""
    out, in_math = [], False
    for ch in str(text):
        if math_ok and ch == "$":
            in_math = not in_math
            out.append(ch)
        elif in_math:
            out.append(ch)
        elif ch in _TEX_SPECIAL:
            out.append(_TEX_SPECIAL[ch])
        elif ch in _TEX_UNICODE:
            out.append(_TEX_UNICODE[ch])
        else:
            out.append(ch)
    return "".join(out)
