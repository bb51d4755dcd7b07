"""`beltdyn paper`: the paper's Tables 1 and 2 reproduced."""

from __future__ import annotations

from pathlib import Path

import typer

from beltdyn.cli.console import console
from beltdyn.cli.failures import guarded
from beltdyn.cli.job import Job, static_pipeline
from beltdyn.cli.options import ForceOpt
from beltdyn.cli.tables import print_paper


def paper(outdir: Path = typer.Option(Path("results/paper"), "--outdir", help="Folder for the HDF5 files and tables.md."),
          configs: Path = typer.Option(Path("configs/paper"), "--configs", help="Folder of the paper configs."),
          force: bool = ForceOpt) -> None:
    """Reproduce the paper's Tables 1 and 2: ours beside the paper's values."""

    def body() -> None:
        from beltdyn.study.paper import CASES, compare, markdown_table

        rows = []
        for case in CASES:
            job = Job(configs / f"{case.config}.toml", outdir / f"{case.config}.h5", [], force)
            rows += compare(case, static_pipeline(job, modal=True).modal)
        print_paper(rows)
        outdir.mkdir(parents=True, exist_ok=True)
        (outdir / "tables.md").write_text(markdown_table(rows), encoding="utf-8")
        worst = max(abs(r.diff_theory_pct) for r in rows)
        console().print(f"24 modes, largest difference to the paper's theoretical values: {worst:.3f} %; "
                         f"wrote {outdir / 'tables.md'}")

    guarded(body)


def register(app: typer.Typer) -> None:
    app.command()(paper)
