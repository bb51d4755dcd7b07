"""`python -m beltdyn.cli`: the console script."""

from beltdyn.cli import run

run()
