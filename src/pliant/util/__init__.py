"""Infrastructure every layer may use, below them all: pliant's disk cache and the
progress events of long reads and builds. It knows nothing of parts or scenes."""
