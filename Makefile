# Two commands do all the set-up on a fresh machine: `make demo` and `make test` (each installs first).
PYTHON ?= python3
DEMO ?= results/demo

.PHONY: install install-docs install-fleet install-export demo fleet paper test test-all test-experiments docs tables bench contrast silverbox tanks boucwen emps discovery leaderboard

install:
	# torch==2.13.0 first: a CPU build; a bare `torch` requirement would pull a multi-GB CUDA build.
	$(PYTHON) -m pip install -q torch==2.13.0 -e ".[test]"

install-docs: install
	$(PYTHON) -m pip install -q -e ".[docs]"

install-fleet: install
	$(PYTHON) -m pip install -q -e ".[fleet]"

install-export: install
	$(PYTHON) -m pip install -q -e ".[export]"

# The end-to-end diagnosis: measurements of an oscillator with an effect that `diagnose` is not told about.
demo: install
	mkdir -p $(DEMO)
	$(PYTHON) -m torchpaml simulate --physics oscillator --set zeta=0.2 --set gain=4 --effect coulomb_friction=0.5 \
		--signal pseudorandom --amplitude 1 --duration 30 --dt 0.05 --noise 0.02 --seed 0 --out $(DEMO)/train.csv
	$(PYTHON) -m torchpaml simulate --physics oscillator --set zeta=0.2 --set gain=4 --effect coulomb_friction=0.5 \
		--signal multisine --amplitude 1 --duration 30 --dt 0.05 --noise 0.02 --seed 1 --out $(DEMO)/validation.csv
	$(PYTHON) -m torchpaml diagnose --data $(DEMO)/train.csv --validation $(DEMO)/validation.csv \
		--physics oscillator --out $(DEMO)

paper: install
	$(PYTHON) experiments/paper/reproduce.py --alpha 4 --alpha 10 --seeds 10 --out results/paper

# pytest exits 5 when it collects no test: that is not a failure of the suite.
# `make test`: the fast lane for every edit (no end-to-end runs), as CI runs it. `make test-all`: the whole suite but the experiments on the measured data, before a release;
# `make test-experiments`: those.
# Both spread the tests over the machine's two cores (pytest-xdist, `-n 2`).
test: install
	$(PYTHON) -m pytest -q -n 2 -m "not slow and not experiment"; status=$$?; if [ $$status -eq 5 ]; then exit 0; else exit $$status; fi

test-all: install-fleet install-export
	$(PYTHON) -m pytest -q -n 2 --dist loadgroup -m "not experiment"; status=$$?; if [ $$status -eq 5 ]; then exit 0; else exit $$status; fi

# The whole experiments on the measured data (Silverbox's and the tanks' discovery, the Bouc-Wen ladder): about four
# minutes; they skip without ../shared/data.
test-experiments: install
	$(PYTHON) -m pytest -q -n 2 -m experiment; status=$$?; if [ $$status -eq 5 ]; then exit 0; else exit $$status; fi

# The documentation site, built strictly (broken links and missing references fail) into site/.
docs: install-docs
	NO_MKDOCS_2_WARNING=1 $(PYTHON) -m mkdocs build --strict --site-dir site

# The docs' result tables, rewritten from the experiments' JSON under results/ (run the experiments first).
tables: install
	$(PYTHON) benchmarks/tables.py --results results --write docs/benchmarks.md docs/tutorials/*.md docs/tutorials/*.md docs/how-to/*.md

bench: install-fleet
	$(PYTHON) benchmarks/bench_simulation.py
	$(PYTHON) benchmarks/bench_recurrence.py
	$(PYTHON) benchmarks/bench_step_control.py
	$(PYTHON) benchmarks/bench_reproduction.py
	$(PYTHON) benchmarks/bench_ranking.py
	$(PYTHON) benchmarks/bench_discovery.py
	$(PYTHON) benchmarks/bench_network.py
	$(PYTHON) benchmarks/bench_diagnosis.py
	$(PYTHON) benchmarks/bench_fleet.py
	$(PYTHON) benchmarks/bench_tracking.py
	$(PYTHON) benchmarks/bench_fit_evaluation.py
	$(PYTHON) benchmarks/bench_same_answer.py --out results/bench_same_answer.json
	$(PYTHON) benchmarks/bench_worst_case.py --lengths 4001 --out results/bench_worst_case.json
	$(PYTHON) benchmarks/bench_worst_case.py --lengths 60001 --rungs "oscillator + coulomb_friction" --discovery-samples 0 --out results/bench_worst_case.json
	$(PYTHON) benchmarks/bench_worst_case.py --lengths --discovery-samples 0 --cases memory_rung pendulum two_output --out results/bench_worst_case.json

contrast: install
	$(PYTHON) experiments/contrast/run.py --out results/contrast

# A simulated fleet of ten units, diagnosed on a local Ray (the fleet how-to's example).
fleet: install-fleet
	$(PYTHON) experiments/fleet/make_fleet.py --out results/fleet/units
	$(PYTHON) -m torchpaml fleet --units results/fleet/units --physics oscillator --out results/fleet/out

# Discovery of forces outside the library, on simulated records (the README's table).
discovery: install
	$(PYTHON) experiments/discovery/run.py --out results/discovery

# The measured benchmarks (they need ../shared/data).
silverbox: install
	$(PYTHON) experiments/silverbox/run.py --out results/silverbox

tanks: install
	$(PYTHON) experiments/cascaded_tanks/run.py --out results/cascaded_tanks
	$(PYTHON) experiments/cascaded_tanks/reference.py

boucwen: install
	$(PYTHON) experiments/boucwen/run.py --out results/boucwen

emps: install
	$(PYTHON) experiments/emps/run.py --out results/emps

# The leaderboard: every registered benchmark (torchpaml.leaderboard.BENCHMARKS) on its protocol, each writing
# results/<name>/<name>.json, then the benchmarks page's tables, the leaderboard among them, from those files.
leaderboard: install
	$(PYTHON) -m torchpaml.leaderboard --results results
	$(PYTHON) benchmarks/tables.py --results results --write docs/benchmarks.md docs/tutorials/*.md
