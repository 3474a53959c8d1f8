# The two commands of the README:
#   make demo   set up this machine and run the SofIA demo (synthetic recordings, all services)
#   make test   set up this machine and run the tests (what CI runs)
.PHONY: install demo test bench lint docs

install:
	@bash scripts/install.sh

demo: install
	.venv/bin/sofia demo

test: install
	.venv/bin/python -m pytest

docs: install
	NO_MKDOCS_2_WARNING=1 .venv/bin/mkdocs build --strict

bench: install
	.venv/bin/python bench/run_all.py

lint: install
	.venv/bin/ruff check . && .venv/bin/ruff format --check . && .venv/bin/mypy
