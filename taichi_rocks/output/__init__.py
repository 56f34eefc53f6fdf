"""Files: the one atomic-write helper (atomic), deterministic .npz (npz), run files (recording: the full layout;
runs: the light layout and load_run), export formats for other tools (formats: one writer interface and its
registry; usd, ply; export: what a frame holds), video and frame writing, render resume. Nothing here runs a
simulation: app/ does, and hands over states and frames."""
