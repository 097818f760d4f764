# Two entry points (see README): `make demo` (main job) and `make test`.
PY := .venv/bin/python

.PHONY: setup demo test lint bench
setup:
	@bash scripts/setup.sh

demo: setup
	$(PY) tools/main_job.py

test: setup
	$(PY) -m pytest -q -n auto --dist loadfile

lint: setup
	.venv/bin/ruff check .

bench: setup
	$(PY) tools/bench.py
