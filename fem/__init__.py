"""fem: meshes, P1/Q1 spaces, vectorised assembly, boundary traces, dual mortar coupling, I/O."""
