"""The Taichi backends a user can ask for, by name (no Taichi here: the command line imports it to list
them). ``gpu`` means CUDA; see taichi_rocks/engine/runtime.py for what each one starts."""

ARCHES = ("cpu", "gpu", "cuda", "vulkan")
