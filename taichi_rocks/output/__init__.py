"""Files: the one atomic-write helper, run files (.npz: recording, the light layout, load_run), export for
other tools (USD, PLY), video and frame writing, render resume."""
