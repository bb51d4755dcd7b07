"""The commands: one module each, with a `register(app)` that adds it to the typer app (`beltdyn.cli.main`
finds every module of this package). A new command is a new module here."""
