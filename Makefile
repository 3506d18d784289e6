# railcal: two commands do everything on a fresh machine.
#   make demo   creates .venv, installs, runs the whole job on the built-in example
#   make test   creates .venv if needed, installs, runs the test suite (make check: its quick tier)
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed

.PHONY: demo test check venv clean bench fmus

$(STAMP): pyproject.toml
	bash scripts/install_system_packages.sh
	$(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip
	$(PY) -m pip install --quiet -e '.[test]'
	touch $(STAMP)

venv: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/railcal demo --out demo_output

# pytest exits 5 when it collects no test; that is a failure of the suite, not a pass.
# TEST_JOBS workers (pytest-xdist). No BLAS thread count is pinned here: results must not
# depend on it. tests/conftest.py caps each worker at cores / workers BLAS threads, for speed
# only (no oversubscription); RAILCAL_TEST_BLAS_CAP=off runs without the cap.
# Each test file stays on one worker except the tests marked `spread`; the dearest groups go
# first (tests/conftest.py orders them; --no-loadscope-reorder keeps that order).
#   make test    the whole suite (what .ci/run runs)
#   make check   the quick tier for development: the tests not marked `slow`
TEST_JOBS ?= 2
PYTEST := $(PY) -m pytest -q -n $(TEST_JOBS) --dist loadgroup --no-loadscope-reorder
NO_TESTS := if [ $$rc -eq 5 ]; then echo "pytest collected no tests" >&2; exit 1; fi; exit $$rc

test: $(STAMP)
	$(PYTEST) tests; rc=$$?; $(NO_TESTS)

check: $(STAMP)
	$(PYTEST) -m "not slow" tests; rc=$$?; $(NO_TESTS)

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
