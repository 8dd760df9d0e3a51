# Two commands do all the set-up on a fresh machine: `make demo` and `make test` (each installs first).
PYTHON ?= python3
OUT ?= results/paper

.PHONY: install demo test bench contrast

install:
	# torch==2.13.0 first: a CPU build; a bare `torch` requirement would pull a multi-GB CUDA build.
	$(PYTHON) -m pip install -q torch==2.13.0 -e ".[test]"

demo: install
	$(PYTHON) experiments/paper/reproduce.py --alpha 4 --alpha 10 --seeds 10 --out $(OUT)

# pytest exits 5 when it collects no test: that is not a failure of the suite.
test: install
	$(PYTHON) -m pytest -q; status=$$?; if [ $$status -eq 5 ]; then exit 0; else exit $$status; fi

bench: install
	$(PYTHON) benchmarks/bench_simulation.py --sizes 8000 800000
	$(PYTHON) benchmarks/bench_reproduction.py

contrast: install
	$(PYTHON) experiments/contrast/run.py --out results/contrast
