"""Running plain-data tasks on worker processes of this machine or on a Ray cluster (tasks.py). It imports
nothing else of the project, so that both the sweeps (app/sweep/) and the benchmark (bench/) can use it."""
