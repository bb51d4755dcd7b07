"""`beltdyn report`: the one page an engineer sends, from a results file alone (never re-running an
analysis): a self-contained HTML file (inline CSS, figures as inline SVG, no script, no network),
printable on A4. Sections for what the file holds (`sections`): the drive (title, configuration hash,
version, the resolved TOML folded away), every warning in words, the layout, the pulleys, the spans,
the tensioner, the modes, a sweep, the forced response and the transient."""

from __future__ import annotations

from pathlib import Path

from beltdyn.errors import OutputError
from beltdyn.plot.data import Results, read_results
from beltdyn.report.html import page
from beltdyn.report.sections import SECTIONS

__all__ = ["build_report", "default_path", "write_report"]


def build_report(res: Results) -> str:
    """The report's HTML text."""
    body = "".join(part(res) for part in SECTIONS)
    return page(f"{res.title}: beltdyn report", body)


def default_path(result: Path) -> Path:
    """RESULT.h5 -> RESULT.html beside it."""
    return Path(result).with_suffix(".html")


def write_report(result: Path, output: Path | None = None) -> Path:
    """Read the results file, write its report (through a temporary file renamed into place), return
    the report's path. A file holding no analysis group is an OutputError (exit 2)."""
    res = read_results(Path(result))
    if not res.groups:
        raise OutputError(f"{result}: holds no results group (/geometry, /static, /modal, /sweep, /transient or "
                          "/response) to report")
    path = Path(output) if output is not None else default_path(Path(result))
    html = build_report(res)
    path.parent.mkdir(parents=True, exist_ok=True)
    tmp = path.with_name(f".{path.name}.tmp")
    tmp.write_text(html, encoding="utf-8")
    tmp.replace(path)
    return path
