# The newcomer's entry points: `make demo` (the main job) and `make test`.
PY := .venv/bin/python

.PHONY: setup test demo lint bench clean-venv

setup:
	@bash scripts/setup.sh

test: setup
	@bash scripts/run_tests.sh

demo: setup
	@$(PY) -m dancenet_core.cli generate examples/example_song.ogg -o out --render

lint: setup
	@.venv/bin/ruff check .

bench: setup
	@$(PY) bench/run.py

clean-venv:
	rm -rf .venv
