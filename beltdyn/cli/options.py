"""The options several commands share (typer's public Argument / Option)."""

from __future__ import annotations

import typer

ConfigArg = typer.Argument(..., help="TOML drive description.", show_default=False)
OutOpt = typer.Option(None, "--output", "-o", help="HDF5 results file [default: results/<config stem>.h5].")
SetOpt = typer.Option(None, "--set", help="Override a dotted config key: KEY=VALUE (TOML literal); KEY= (empty "
                      "value) removes the key, as --unset KEY.", metavar="KEY=VALUE")
UnsetOpt = typer.Option(None, "--unset", help="Remove a dotted config key (e.g. tension.target, to switch to "
                        "tension.mode = \"spring\"); an error if the file does not have it.", metavar="KEY")
ForceOpt = typer.Option(False, "--force", help="Replace a results file written for a different configuration.")
ForceLargeOpt = typer.Option(False, "--force-large",
                             help="Write histories larger than transient.max_output_mb (default 1000 MB).")
FmaxOpt = typer.Option(None, "--fmax", min=0.0,
                       help="With --rtol: choose each span's model and mesh (spring, string or ANCF) for the modes "
                            "below FMAX Hz: the cheapest whose estimated error is within RTOL of the converged ANCF "
                            "drive; the choice goes into the resolved configuration ([spans]).")


def overrides(sets: list[str] | None, unsets: list[str] | None) -> list[str]:
    """The configuration overrides of --set KEY=VALUE and --unset KEY (passed on as KEY=, `config.apply_override`),
    the removals after the assignments."""
    return [*(sets or []), *(f"{key.strip()}=" for key in unsets or [])]
