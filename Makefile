# The newcomer's entry points: `make demo` (the main job) and `make test`.
PY := .venv/bin/python

.PHONY: setup test check-data demo lint bench clean-venv

setup:
	@bash scripts/setup.sh

# The linters first (seconds): ruff, and import-linter's layering contracts (pyproject.toml). Then the suite on
# bpy 4.5 LTS (.venv, Python 3.11) and the add-on's tests on bpy 5.2 LTS (.venv-blender52, Python 3.13), each on
# two workers, naming its 15 slowest tests.
test: lint
	@bash scripts/run_tests.sh

# The checks on the real motion capture data beyond seconds of it (the `data` marker: the whole dataset built, whole
# sequences fitted; ../shared/data or $DANCENET_DATA), which `make test` leaves out: run before a change to the
# data or a model (docs/training.md).
check-data: setup
	@bash scripts/run_tests.sh --data

# The demo replaces its own example outputs in out/, so it runs again and again (user songs keep the no-overwrite rule).
demo: setup
	@$(PY) -m dancenet_core.cli generate examples/example_song.ogg -o out --render --overwrite

lint: setup
	@.venv/bin/ruff check .
	@.venv/bin/lint-imports --no-cache

bench: setup
	@$(PY) bench/run.py

clean-venv:
	rm -rf .venv .venv-blender52
