"""The offscreen GGUI renderer: kernels (the background layer), meshes, camera, window, overlays, the
Renderer (one frame) and the pipeline (render_scene: a whole render to frames and a video)."""
