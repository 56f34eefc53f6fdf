"""Files: the one atomic-write helper, recording of runs (.npz), video and frame writing, render resume."""
