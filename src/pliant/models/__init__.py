"""Models: the accurate elastica (2D) and, later, the 3D rod and the real-time network."""
