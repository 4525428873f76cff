# Two commands on a fresh machine:  make run   (main job on bundled data)   make test
PY := $(shell scripts/find-python.sh)
VENV := .venv
BIN := $(VENV)/bin
OUT ?= out

.PHONY: run test test-extended bench bench-fit clean lock
# constraints.txt pins every package to the versions the committed numbers were produced with
$(BIN)/.installed: pyproject.toml constraints.txt
	@test -n "$(PY)" || { echo "no Python >= 3.12 found (see scripts/find-python.sh)"; exit 1; }
	$(PY) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet -c constraints.txt -e ".[test]"
	touch $@

# re-pin constraints.txt to this environment's versions (then re-run what docs/ reports)
lock: $(BIN)/.installed
	{ sed -n '1,2p' constraints.txt; $(BIN)/python -m pip freeze --exclude-editable | grep -v '^pip=='; } > constraints.txt.new
	mv constraints.txt.new constraints.txt

run: $(BIN)/.installed
	$(BIN)/python scripts/main_job.py -o $(OUT)

# the threaded batch-sampler tests and the NUTS tests run in a process of their own (they compile
# many programs; tests/conftest.py drops compiled programs when a process holds many, as a long-lived
# xdist worker otherwise runs out of memory mappings (vm.max_map_count) inside XLA). Every test process
# computes on one core (tests/conftest.py), so that process runs beside the two-worker pool
# rather than before it: its log is printed when both are done, and either failing fails the target
# (the pool takes the longest files first: tests/conftest.py, LONGEST_FILES)
test: $(BIN)/.installed
	@log=$$(mktemp); \
	$(BIN)/python -m pytest -q tests/test_batch_sampler.py tests/test_nuts.py > $$log 2>&1 & nuts=$$!; \
	$(BIN)/python -m pytest -q -n 2 --dist loadfile --no-loadscope-reorder --durations=70 --ignore tests/test_batch_sampler.py --ignore tests/test_nuts.py; \
	pool=$$?; wait $$nuts; nuts_rc=$$?; \
	echo "--- tests/test_batch_sampler.py and tests/test_nuts.py (run beside the pool):"; cat $$log; rm -f $$log; \
	test $$pool -eq 0 && test $$nuts_rc -eq 0

# the long trails and end-to-end runs `make test` leaves out for its time (marker `extended`)
test-extended: $(BIN)/.installed
	TORSIONFIT_EXTENDED_TESTS=1 $(BIN)/python -m pytest -q -n 2 --dist loadfile -m extended --durations=20

bench: $(BIN)/.installed
	$(BIN)/python benchmarks/bench_hysteresis_scan.py

# the NumPy/SciPy comparison needs scipy, which is not a package dependency
bench-fit: $(BIN)/.installed
	$(BIN)/python -m pip install --quiet scipy
	$(BIN)/python benchmarks/bench_full_fit.py

clean:
	rm -rf $(VENV) $(OUT)
