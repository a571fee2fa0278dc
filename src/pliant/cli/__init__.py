"""Command-line interface (typer): solve problem files, run the demo."""
