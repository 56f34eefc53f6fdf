"""What a scene asks for: the scene models (TOML -> validated, frozen pydantic models with a JSON Schema), the
accuracy presets and the Plan (which passes run, decided once). Never imports Taichi."""
