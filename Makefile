# retarget-notebooks — two commands do everything (see README):
#   make        set up .venv, build the embedded dataset, execute every notebook into build/notebooks/
#               and write the offline HTML book build/book/index.html
#   make test   unit tests + every notebook executed by nbval (the tests marked `slow` are left out)
#   make test-slow   the tests marked `slow` (minutes each: compiled steps, the ESO identity, the
#               benchmarks' rows, torchrun, sweeps); CI runs them after `make test`
#   make workshop   the workshop notebooks (notebooks/learning_path.yaml) two at a time, then the book
#   make book   the HTML book alone, from what is executed (build/notebooks/) or committed (notebooks/)
#   make book-teacher   the book with the exercises' reference answers (notebooks/solutions/) in the
#               exercise cells, into build/book-teacher/ (never hand it to students)
#   make unit-fast   the library tests that need neither the built data nor minutes (a bare checkout)
#   make tables      every table of both papers, recomputed into results/ with provenance (the seconds each part took: results/*.provenance.json)
# Both are idempotent: stamps and the data cache make a second run reuse what is built.

PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin
STAMP  := $(VENV)/.installed
NOTEBOOKS := $(sort $(wildcard notebooks/[0-9][0-9]*_*.ipynb))
export VTK_DEFAULT_OPENGL_WINDOW := vtkEGLRenderWindow
export RETARGET_PROFILE ?= fast
# the time of each step, printed at the end of `make` and `make test` (.ci/step_times.py)
RUN_ID := $(shell date +%s%N)
STEP   := @$(PYTHON) .ci/step_times.py $(RUN_ID)
# two notebooks or two test workers at a time on a 2-core machine, one thread each: OpenMP, MKL
# and Mesa's llvmpipe rasteriser (PyVista's offscreen renders), which otherwise starts a thread per
# core (more threads than cores oversubscribes and spins: notebook 07b took 99 s beside 04 with
# llvmpipe's threads, 65 s with one)
JOBS   ?= 2
ONE_THREAD := OMP_NUM_THREADS=1 MKL_NUM_THREADS=1 LP_NUM_THREADS=1

.PHONY: all setup system-deps data notebooks book book-teacher workshop test test-slow unit unit-fast unit-threads lint nbval bench tables clean-build

all: notebooks
	$(STEP) report make

# Debian packages: offscreen OpenGL (EGL + Mesa) for pyvista and the CMU clips (assimp-testmodels).
# Installed only when missing and we are root; otherwise the data step falls back to `apt-get download`.
system-deps:
	@bash .ci/system-deps.sh

$(STAMP): pyproject.toml constraints-cpu.txt
	$(STEP) start setup
	$(MAKE) system-deps
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/pip install -q --upgrade pip
	$(BIN)/pip install -q -c constraints-cpu.txt torch
	$(BIN)/pip install -q -c constraints-cpu.txt -e '.[dev,fbx]'
	bash .ci/node-deps.sh $(VENV)
	touch $(STAMP)
	$(STEP) end setup

setup: $(STAMP)

data: $(STAMP)
	$(STEP) start data
	$(BIN)/retarget data build
	$(STEP) end data

# independent notebooks $(JOBS) at a time, the longest first (build/notebooks/timings.json, else
# benchmarks/notebook-times.json)
notebooks: data
	@mkdir -p build/notebooks
	$(STEP) start notebooks
	$(ONE_THREAD) $(BIN)/python -m retarget_lib.notebook.runner --out build/notebooks --jobs $(JOBS) $(NOTEBOOKS)
	$(STEP) end notebooks
	$(STEP) start book
	$(BIN)/python -m retarget_lib.notebook.book --executed build/notebooks --out build/book
	$(STEP) end book

# no execution: pages from build/notebooks/ where `make` or `make workshop` executed them, else the
# outputs committed in notebooks/ (each page says which)
book: $(STAMP)
	$(BIN)/python -m retarget_lib.notebook.book --executed build/notebooks --out build/book

# the notebooks with a solutions file executed with their reference answers in the exercise cells
# (build/notebooks-teacher/), the others as `make`/`make book` show them plus their old solution cells
book-teacher: data
	@mkdir -p build/notebooks-teacher
	$(ONE_THREAD) $(BIN)/python -m retarget_lib.notebook.runner --out build/notebooks-teacher \
		--solutions --jobs $(JOBS) $(NOTEBOOKS)
	$(BIN)/python -m retarget_lib.notebook.book --teacher --executed build/notebooks-teacher \
		--executed build/notebooks --out build/book-teacher

# the workshop path (docs/book-and-workshop.md, docs/teachers_guide.md): the notebooks marked `workshop: yes`
# in notebooks/learning_path.yaml, fast profile, two at a time with one thread each on a 2-core laptop;
# the runner prints every notebook it leaves out and why. Add WORKSHOP_FLAGS=--force to time a re-run.
workshop: data
	@mkdir -p build/notebooks
	$(STEP) start workshop-notebooks
	$(ONE_THREAD) $(BIN)/python -m retarget_lib.notebook.runner --out build/notebooks \
		--workshop --jobs $(JOBS) $(WORKSHOP_FLAGS)
	$(STEP) end workshop-notebooks
	$(BIN)/python -m retarget_lib.notebook.book --executed build/notebooks --out build/book
	$(STEP) report "make workshop"

# $(JOBS) xdist workers, one torch/OpenMP thread each; the 15 slowest tests printed at the end
PYTEST := $(ONE_THREAD) $(BIN)/pytest

unit: data
	$(PYTEST) -q -n $(JOBS) --dist loadfile tests

# no data build: tests marked `data` or `slow` (pyproject.toml) are left out
unit-fast: $(STAMP)
	$(PYTEST) -q -n $(JOBS) --dist loadfile -m "not data and not slow" tests

nbval: data
	$(PYTEST) -q -n $(JOBS) --dist loadfile --nbval-lax notebooks

test: data lint
	$(STEP) start pytest-unit+nbval
	$(PYTEST) -q -n $(JOBS) --dist loadfile --durations=15 -m "not slow" tests --nbval-lax notebooks
	$(STEP) end pytest-unit+nbval
	$(STEP) report "make test"

# loadscope: a module's tests stay together (their module fixtures), a test class's too; the
# wrong-answer notebook runs (tests/test_exercises.py) are two classes, one per worker
test-slow: data
	$(STEP) start pytest-slow
	$(PYTEST) -q -n $(JOBS) --dist loadscope --durations=10 -m slow tests
	$(STEP) end pytest-slow
	$(STEP) report "make test-slow"

# ruff (pycodestyle, pyflakes, isort, bugbear, pyupgrade; line length 100) and its formatter over the
# library, tests, tools, benchmarks and CI scripts, then mypy (config: pyproject.toml); `make test` runs it first
lint: $(STAMP)
	$(BIN)/ruff check retarget_lib tests tools benchmarks .ci
	$(BIN)/ruff format --check retarget_lib tests tools benchmarks .ci
	$(BIN)/mypy

# the library tests once more in one process with two OpenMP threads: results must not depend on the
# thread count (tolerances, never exact equality between kernels); run by CI after `make test`
# (the modules marked `tooling`, file formats, untrusted input, notebooks and the book, ran there and
# hold nothing a thread count can change: left out here)
unit-threads: $(STAMP)
	OMP_NUM_THREADS=2 MKL_NUM_THREADS=2 $(BIN)/pytest -q -p no:cacheprovider -m "not data and not slow and not tooling" tests

bench: data
	$(BIN)/retarget bench

# the reviewer's full recompute: every row of every table, every clip, into results/ (kept in the
# repository, each per-case CSV with a .provenance.json); the notebooks read these and re-run a subset
tables: data
	$(BIN)/retarget evaluate --all --out results
	$(BIN)/retarget evaluate --status

clean-build:
	rm -rf build
