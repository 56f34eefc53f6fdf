# The two commands a new user needs:  make demo  (renders the default scene to a video)  and  make test.
VENV  ?= .venv
PY    := $(VENV)/bin/python
STAMP := $(VENV)/.installed
SCENE ?= scenes/convoy.toml

.PHONY: setup demo test lint bench clean native game game-frames

setup: $(STAMP)

$(STAMP): pyproject.toml tools/setup.sh
	bash tools/setup.sh $(VENV)
	touch $(STAMP)

demo: setup
	$(VENV)/bin/taichi-rocks render $(SCENE) --overwrite

# the Panda3D game (examples/panda3d_game.py; Panda3D comes with setup): play it in a window (offscreen where there
# is no display), or render GAME_FRAMES frames of it offscreen, a recorded drive at the wheel, into GAME_OUT
GAME_FRAMES ?= 300
GAME_OUT ?= renders/game

game: setup
	$(PY) examples/panda3d_game.py

game-frames: setup
	$(PY) examples/panda3d_game.py --offscreen --frames $(GAME_FRAMES) --out $(GAME_OUT) --overwrite

# the suite on TEST_WORKERS processes (pytest-xdist), a test file per process at a time (its module fixtures and
# compiled kernels stay together), the slowest files first (tests/conftest.py SLOW_FILES, kept in that order by
# --no-loadscope-reorder); each process holds one Taichi runtime. 2 suits a 2-core machine.
TEST_WORKERS ?= 2

# (native/ is built first where cmake and a C++ compiler exist; elsewhere tests/native/ skips, saying why)
test: setup
	@if command -v cmake >/dev/null && command -v c++ >/dev/null; then $(MAKE) --no-print-directory native; \
	else echo "make test: no cmake or no c++ here: native/ is not built and tests/native/ is skipped" >&2; fi
	$(PY) -m pytest -q -n $(TEST_WORKERS) --dist loadfile --no-loadscope-reorder

# the native host (docs/native.md): native/build/librocks.so and native/build/rocks_run, over the C API of the
# taichi wheel in $(VENV); cmake and a C++17 compiler (tools/setup.sh installs them where they are missing)
native: setup
	cmake -S native -B native/build -DPYTHON=$(abspath $(PY)) -DCMAKE_BUILD_TYPE=Release >/dev/null
	cmake --build native/build -j $(TEST_WORKERS)

# ruff with the rules of pyproject.toml ([tool.ruff]); .ci/run runs it before the tests
lint: setup
	$(VENV)/bin/ruff check taichi_rocks tests tools examples

bench: setup
	$(VENV)/bin/pip install -q -e '.[bench]'
	$(VENV)/bin/taichi-rocks bench

clean:
	rm -rf $(VENV) renders/*/ .pytest_cache native/build
