"""The offscreen GGUI renderer: kernels, meshes, camera, Renderer and the render pipeline."""
