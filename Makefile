# servoface: every target sets itself up on a fresh machine (system check, .venv, install).
PYTHON ?= python3
VENV   := .venv
PY     := $(VENV)/bin/python
STAMP  := $(VENV)/.installed-stamp
export PYOPENGL_PLATFORM := egl

.PHONY: demo test bench setup check-system lint clean

$(STAMP): pyproject.toml scripts/check_system.sh
	@bash scripts/check_system.sh
	@$(PYTHON) -c 'import sys; sys.exit(0 if sys.version_info >= (3, 11) else "servoface needs Python >= 3.11, found " + sys.version.split()[0])'
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	@$(PY) -m pip install --quiet --disable-pip-version-check --upgrade pip
	@$(PY) -m pip install --quiet --disable-pip-version-check -e '.[dev]'
	@touch $(STAMP)

setup: $(STAMP)

check-system:
	@bash scripts/check_system.sh

demo: $(STAMP)
	$(VENV)/bin/servoface demo --out out/demo

test: $(STAMP)
	$(PY) -m pytest -q -p no:cacheprovider

bench: $(STAMP)
	$(VENV)/bin/servoface bench

lint: $(STAMP)
	$(VENV)/bin/ruff check controller sim hardware calibration tests
	$(VENV)/bin/ruff format --check controller sim hardware calibration tests
	@# mypy reads the four folders as the package they install as (servoface.*) through a tree of links
	@rm -rf build/typecheck && mkdir -p build/typecheck/servoface
	@for d in controller sim hardware calibration; do ln -s "$(CURDIR)/$$d" build/typecheck/servoface/$$d; done
	cd build/typecheck && $(CURDIR)/$(VENV)/bin/mypy --config-file $(CURDIR)/pyproject.toml -p servoface

clean:
	rm -rf $(VENV) out build *.egg-info
