"""Drawing: the offscreen or shown GGUI renderer: kernels (the background layer), meshes, cameras, window,
overlays, the view's panel and free camera, and the Renderer (one frame, in parts: see render/renderer.py).
What the ``render`` and ``view`` commands do with it (the frame loop, outputs, resume; the window's loop and
clock) is app/'s."""
