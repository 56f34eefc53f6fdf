"""What a scene asks for: the scene models (TOML -> validated, frozen pydantic models with a JSON Schema), the
choices and ranges of their keys as every room reads them (keys.py), the accuracy presets, the Plan (which
passes run, decided once) and the random-stream ids of every room (streams.py). Never imports Taichi."""
