# make demo: set up .venv, generate the mesh, run the default scene, write its output and a PNG.
# make test: the same set-up, then the whole test suite.
# make docs: the user guide as a website in build/site/ (MkDocs; the options reference regenerated from the catalog).
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.hyperelastic-installed
KERNELS_STAMP := $(VENV)/.kernels-built
DEMO_SCENE ?= bend
DEMO_LEVEL ?= 3

.PHONY: all setup demo test docs clean

all: setup

setup: $(KERNELS_STAMP)

$(STAMP): requirements.txt setup.py scripts/bootstrap.sh
	bash scripts/bootstrap.sh

# rebuild the compiled kernels when their source changes (no PETSc rebuild): the loops, and each
# material's header (setup.py instantiates the loops once per hyperelastic/physics/materials/NAME.h)
KERNEL_SOURCES := hyperelastic/discretization/_kernels.c $(wildcard hyperelastic/discretization/*.h) \
                  $(wildcard hyperelastic/physics/materials/*.h)
$(KERNELS_STAMP): $(STAMP) setup.py $(KERNEL_SOURCES)
	$(PY) setup.py -q build_ext --inplace -f >/dev/null
	touch $@

demo: setup
	mkdir -p output
	$(VENV)/bin/hyperelastic run $(DEMO_SCENE) -level $(DEMO_LEVEL) -output output/demo.h5
	$(VENV)/bin/hyperelastic plot output/demo.h5 -o output/demo.png

# (the package's bytecode compiled first: where PYTHONDONTWRITEBYTECODE is set, as on this project's machines, every
# one of the suite's ~1,000 child runs would compile the package again, ~0.17 s each)
test: setup
	$(PY) -m compileall -q hyperelastic
	PATH="$(abspath $(VENV))/bin:$$PATH" $(PY) -m pytest -q -n 2 --dist loadfile --durations=30 tests

docs: setup
	$(PY) -m hyperelastic.app.catalog --reference > docs/reference/options.md
	$(VENV)/bin/mkdocs build --strict
	@echo "the guide: build/site/index.html"

clean:
	rm -rf output build hyperelastic/discretization/_kernels*.so
