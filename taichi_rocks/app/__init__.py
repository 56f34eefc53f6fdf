"""What the commands orchestrate: a scene run frame by frame into its outputs. ``simulate`` (simulate.py: the
run file), ``export`` (export.py: USD, PLY, ... through output/formats.py), ``render`` (render.py: frames and a
video, resumable) and ``view`` (view.py: the window's loop, timeline.py: its clock). The rooms below do the
work: engine/ simulates, render/ draws, output/ writes; cli.py parses, calls these and prints."""
