# Two entry points for a fresh machine: `make run` (full rig run) and `make test` (the suite).
VENV ?= .venv
PY := $(VENV)/bin/python
STAMP := $(VENV)/.installed

.PHONY: setup ament-index bytecode run test test-fast lint typecheck bench bench-setup

$(STAMP): requirements.txt setup.py test/support/pyproject.toml
	python3 -m venv $(VENV)
	$(PY) -m pip install -q --upgrade pip
	$(PY) -m pip install -q -r requirements.txt
	$(PY) -m pip install -q --no-deps -e .
	$(PY) -m pip install -q --no-deps -e test/support  # lubrig_testkit: helpers of test/ and bench/
	touch $(STAMP)

# lubrig_interfaces (ROS 2 interface package, ament_cmake + rosidl): configured, built and installed
# into the venv prefix with the machine's cmake and gcc, from the generator wheels in requirements.txt
# (docs/interfaces.md). Rebuilt when a .msg, its CMakeLists.txt or package.xml changes, or when the
# venv is (re)installed; the files of the previous install are removed first (install_manifest.txt).
IFACE_SRC := lubrig_interfaces
IFACE_BUILD := build/lubrig_interfaces
IFACE_STAMP := $(VENV)/.lubrig_interfaces
IFACE_FILES := $(IFACE_SRC)/CMakeLists.txt $(IFACE_SRC)/package.xml $(wildcard $(IFACE_SRC)/msg/*.msg) \
	$(wildcard $(IFACE_SRC)/srv/*.srv)
VENV_ABS = $(abspath $(VENV))
JOBS ?= $(shell nproc 2>/dev/null || echo 2)

$(IFACE_STAMP): $(STAMP) $(IFACE_FILES)
	@if [ -f $(IFACE_BUILD)/install_manifest.txt ]; then xargs rm -f < $(IFACE_BUILD)/install_manifest.txt; fi
	rm -rf $(IFACE_BUILD)
	CMAKE_PREFIX_PATH=$(VENV_ABS) cmake -S $(IFACE_SRC) -B $(IFACE_BUILD) --log-level=WARNING \
		-DCMAKE_BUILD_TYPE=Release -DBUILD_TESTING=OFF \
		-DCMAKE_INSTALL_PREFIX=$(VENV_ABS) -DPython3_EXECUTABLE=$(VENV_ABS)/bin/python
	cmake --build $(IFACE_BUILD) -j $(JOBS) -- --no-print-directory > $(IFACE_BUILD)/build.log 2>&1 \
		|| { tail -40 $(IFACE_BUILD)/build.log; exit 1; }
	cmake --install $(IFACE_BUILD) > $(IFACE_BUILD)/install.log
	$(PY) -c "import lubrig_interfaces.msg"
	touch $@

# The Foxglove WebSocket client of test/test_view_foxglove.py: Foxglove's npm packages, pinned in
# test/support/foxglove_client/package-lock.json, installed into its node_modules (gitignored).
# Skipped with a note where npm is missing (that test then fails, saying so).
CLIENT_DIR := test/support/foxglove_client
CLIENT_STAMP := $(CLIENT_DIR)/node_modules/.installed

$(CLIENT_STAMP): $(CLIENT_DIR)/package.json $(CLIENT_DIR)/package-lock.json
	@if command -v npm >/dev/null 2>&1; then \
		cd $(CLIENT_DIR) && npm ci --no-audit --no-fund --loglevel=error && touch node_modules/.installed; \
	else echo "npm not found: the Foxglove client of test/test_view_foxglove.py is not installed"; fi

# lubrig_ros in the venv prefix's ament index, as colcon's ament_python build (--symlink-install)
# installs it: share/ament_index/.../packages/lubrig_ros, share/lubrig_ros/{package.xml,launch,config}
# and lib/lubrig_ros/<console script>, all symlinks (to the work tree's files, and to .venv/bin/<name>),
# from setup.py's data_files and entry points. Run by every make setup (cheap, changes only what is
# out of date, atomically), so `ros2 run lubrig_ros plant` / `ros2 launch lubrig_ros rig.launch.py`
# work with AMENT_PREFIX_PATH=.venv on a machine with ROS 2 (README "ros2 run and ros2 launch").
ament-index: $(STAMP)
	$(PY) -m lubrig_ros.app.processes.ament_install --prefix $(VENV) --source .

# lubrig_ros's bytecode, written once here: an editable install compiles nothing, and where
# PYTHONDONTWRITEBYTECODE is set (these machines) every node process of a rig would otherwise
# compile the modules it imports at each start (docs/benchmarks.md, start-up). Only what is out of
# date is compiled again.
bytecode: $(STAMP)
	$(PY) -m compileall -q lubrig_ros

setup: $(STAMP) $(IFACE_STAMP) $(CLIENT_STAMP) ament-index bytecode

# The main job: the node suite (belt_drive, plant, analysis, recorder) on study case 1 in simulated
# time, recorded to runs/latest/bag, then the report; the last line printed is the report's path.
run: setup
	$(VENV)/bin/lubrig rig --case 1 --duration 10 --run-dir runs/latest --force

# The whole suite (ROS node processes over DDS included); the README's test command.
# Every ROS test file runs in a pytest process of its own (lubrig_testkit/suite.py says why).
test: setup
	$(PY) -m lubrig_testkit.suite $(PYTEST_ARGS)

# The ROS-free, quick tier: no node processes, no DDS, no long runs (see test/conftest.py).
test-fast: setup
	$(PY) -m pytest -q -m "not ros and not slow" $(PYTEST_ARGS) test

# ruff check (including complexity, C901 at 15), ruff format --check and vulture (dead code and
# test-only helpers in the package; settings and whitelist: pyproject.toml [tool.vulture]): all gate
# CI (.ci/run).
lint: setup
	$(VENV)/bin/ruff check lubrig_ros test bench launch
	$(VENV)/bin/ruff format --check lubrig_ros test bench launch
	$(VENV)/bin/vulture

# mypy on the whole package (settings in pyproject.toml [tool.mypy]); must report no issues.
typecheck: setup
	$(VENV)/bin/mypy

# Benchmark-only packages (requirements-bench.txt: numbalsoda, built from source with gcc/g++ in
# about a minute; CMAKE_POLICY_VERSION_MINIMUM lets CMake 4 configure its CMakeLists, see there).
BENCH_STAMP := $(VENV)/.bench-installed

$(BENCH_STAMP): $(STAMP) requirements-bench.txt
	CMAKE_POLICY_VERSION_MINIMUM=3.5 $(PY) -m pip install -q -r requirements-bench.txt
	$(PY) -c "import numbalsoda"
	touch $@

bench-setup: setup $(BENCH_STAMP)

# Benchmarks print their figures (docs/benchmarks.md records them with these commands).
bench: setup bench-setup
	$(PY) bench/bench_integrator.py
	$(PY) bench/bench_online_wavelet.py
	$(PY) bench/bench_recorder.py --seconds 10 --rate 1000
	$(PY) bench/bench_sweep.py --points 16 --duration 20 --workers 1 2
	$(PY) bench/bench_realtime.py --duration 60
	$(PY) bench/bench_replay.py
