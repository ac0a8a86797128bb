# The newcomer's entry points: `make demo` (the main job) and `make test`.
PY := .venv/bin/python

.PHONY: setup test test-blender5 demo lint bench clean-venv

setup:
	@bash scripts/setup.sh

# The linters first (seconds): ruff, and import-linter's layering contracts (pyproject.toml).
test: lint
	@bash scripts/run_tests.sh

# The add-on tests again on Blender 5.0's API (bpy 5.0.1 in its own .venv-blender5; `make test` runs 4.5 LTS).
test-blender5: setup
	@bash scripts/test_blender5.sh

demo: setup
	@$(PY) -m dancenet_core.cli generate examples/example_song.ogg -o out --render

lint: setup
	@.venv/bin/ruff check .
	@.venv/bin/lint-imports --no-cache

bench: setup
	@$(PY) bench/run.py

clean-venv:
	rm -rf .venv .venv-blender5
