# railcal: two commands do everything on a fresh machine.
#   make demo   creates .venv, installs, runs the whole job on the built-in example
#   make test   creates .venv if needed, installs, runs the test suite
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test venv clean bench fmus

$(STAMP): pyproject.toml
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/railcal demo --out demo_output

# pytest exits 5 when it collects no test; that is a failure of the suite, not a pass.
# TEST_JOBS workers (pytest-xdist), each on one BLAS thread: the suite's linear algebra is on
# matrices of a few hundred rows, where a second BLAS thread costs more than it gives (one
# stationary diagnosis: 100 s on one thread, 136 s on two), so the cores go to workers instead.
# Each test file stays on one worker except the tests marked `spread` (tests/conftest.py).
TEST_JOBS ?= 2
test: $(STAMP)
	OPENBLAS_NUM_THREADS=1 OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 $(PY) -m pytest -q -n $(TEST_JOBS) --dist loadgroup tests; rc=$$?; \
	if [ $$rc -eq 5 ]; then echo "pytest collected no tests" >&2; exit 1; fi; exit $$rc

# FMUs of the car and the box-type vehicle, FMI 2.0 and 3.0 (win64 too when mingw-w64 is installed:
# Debian packages gcc-mingw-w64-x86-64 binutils-mingw-w64-x86-64)
fmus: $(STAMP)
	$(PY) scripts/build_fmus.py --out build/fmus

# Benchmarks print their figures; bench_fdd synthesises its 30 x 90 km campaign once (about 1.5 GB).
bench: $(STAMP)
	$(PY) scripts/bench_fdd.py
	$(PY) scripts/bench_calibrate_car.py
	$(PY) scripts/bench_pso_box.py
	$(PY) scripts/bench_fmu.py

clean:
	rm -rf $(VENV) demo_output build *.egg-info
