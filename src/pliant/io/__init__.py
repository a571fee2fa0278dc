"""File edges: problem files (TOML, SI units) to and from the core vocabulary."""
