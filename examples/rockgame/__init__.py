"""The Panda3D game of examples/panda3d_game.py, in parts: the scene and its road (scene.py), the player's car
model (car.py), what drives it (controls.py: the keyboard or a recorded drive), the rocks drawn from the mirror
``changes()`` keeps (rocks.py), meshes and textures (meshes.py), the vehicles (vehicles.py), the hits' flashes and
marks (hits.py), the frame budget (budget.py) and the game itself (game.py); beside them, the driver that wrote
the shipped drive (autopilot.py), the budget measured (measure.py) and the README's stills (media.py).

Panda3D is imported only here, never by the taichi_rocks package: the game stands where any game engine would,
on the package's public face (``Simulation.drive``, ``advance_to``, ``impacts``, ``changes``) and on its public
motion and config modules (the vehicles' body shapes, the cabins, the recorded drives).
"""
