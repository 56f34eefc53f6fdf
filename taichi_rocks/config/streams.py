"""Random-stream ids: every counter-based random number of the project draws from a stream declared here.

A random number is a hash of a few integers, one of which is its stream id: two draws of one rock (and step)
are independent only if their streams differ. Ids are salts of three separate hashes (families); within a
family no two streams may share an id:

  engine  engine/randomness.py ``uniform01(seed, rock id, step, stream)``: the kernels' draws;
  look    render/rocklook.py ``_unit(rock id, salt)``: what a rock looks like (colour, outline, thinning);
  export  output/shapes.py ``uniforms(ids, stream)``: the exported instances' prototypes.

A stream of ``count`` ids takes ``first`` .. ``first + count - 1`` (draw k of it uses ``id(k)``). A new stream
is one line below, on ids no other stream of its family takes (tests/config/test_keys.py checks). The launch
models (engine/launch/) share one block: a scene runs one model, so each model takes the ids of the block it
likes (its ``STREAMS``, checked to lie in the block) and a new model adds no line here. The engine's ids are
those the kernels have always used: changing one changes every run.
"""

from __future__ import annotations

from dataclasses import dataclass

__all__ = ["Stream", "STREAMS", "FAMILIES"]

FAMILIES = ("engine", "look", "export")


@dataclass(frozen=True)
class Stream:
    """Ids ``first`` .. ``first + count - 1`` of a family's hash, and what draws them."""

    family: str
    first: int
    count: int
    what: str

    @property
    def ids(self) -> range:
        return range(self.first, self.first + self.count)

    def id(self, k: int) -> int:
        """The k-th id of the stream."""
        if not 0 <= k < self.count:
            raise IndexError(f"stream {self.what!r} has {self.count} ids, not {k + 1}")
        return self.first + k


STREAMS: list[Stream] = []


def _stream(family: str, first: int, count: int, what: str) -> Stream:
    s = Stream(family, first, count, what)
    STREAMS.append(s)
    return s


# engine: (seed, rock id, step, stream)
RECYCLE_TRIES = _stream("engine", 0, 64, "engine/bed.py: a recycled rock's row across the leading crescent, by "
                                         "rejection: attempt k draws the row from 2k and its acceptance from 2k + 1")
RECYCLE_CHORD = _stream("engine", 101, 1, "engine/bed.py: where on its chord the recycled rock lands")
LAUNCH = _stream("engine", 201, 99, "engine/launch/: the launch model's draws (each model's STREAMS)")
LAUNCH_SPIN = _stream("engine", 301, 3, "engine/tumble.py: the scatter of a launched stone's spin (direction z, "
                                        "azimuth, radius in the unit ball)")
INITIAL_ORIENTATION = _stream("engine", 311, 3, "engine/setup.py: a rock's orientation before the first step "
                                                "(Shoemake's three uniforms)")
DUST = _stream("engine", 401, 7, "config/effects/dust.py: a dust particle's place in the emission box (across, "
                                 "along, up), its lift, its random walk (x, y, z); (seed, particle, step)")

# look: (rock id, salt)
LOOK_COLOUR = _stream("look", 1, 3, "render/rocklook.py: a rock's colour (brown share, brightness, darkening)")
LOOK_THIN = _stream("look", 7, 1, "render/splat.py: which far resting rocks the level of detail keeps")
LOOK_SHAPE = _stream("look", 11, 7, "render/rocklook.py: a resting rock's outline (A2, A3, phase 2, phase 3, "
                                    "facet tilt, A5, phase 5)")
LOOK_PROTOTYPE = _stream("look", 19, 1, "render/tumbling.py: which rock prototype a flying rock is drawn as")

# export: (id, stream)
EXPORT_PROTOTYPE = _stream("export", 7, 1, "output/instances.py: which rock prototype an instance draws")
