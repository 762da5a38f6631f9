# Set-up and everyday commands. Only python3 (3.11+) is needed on the machine.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: acados ros f1tenth-gym car-loop demo demo-quick test test-slow test-all lint bench bench-breakdown tracks-table study-tracks study-cars study-pace study-fullsize study-data faults results clean

# PyTorch first and pinned exactly: a looser pin pulls a multi-gigabyte CUDA build.
$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet torch==2.13.0

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[train]'
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[train,test]'
	touch $@ $(VENV)/.installed

# acados for `nmpc-acados` and `nmpc-acados-dynamic` (the real-time iterations, tested in CI): the `acados`
# extra (a 13 MB wheel and Cython; about 15 s). A C compiler and make build each solver on first use (4 to
# 15 s); the tests keep theirs in .pytest_cache/d/rkmpc/acados, the commands in ~/.cache/rkmpc/acados.
$(VENV)/.installed-acados: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[acados]'
	touch $@

acados: $(VENV)/.installed-acados

# ROS 2 for `rkmpc node` and `rkmpc sim-node`: the `ros` extra, then ackermann_msgs generated from its
# definition (ros/ackermann_msgs) and installed into the venv beside the wheels' message packages.
ROS_MSGS := ros/build_msgs.sh ros/ackermann_msgs/CMakeLists.txt ros/ackermann_msgs/package.xml $(wildcard ros/ackermann_msgs/msg/*.msg)
$(VENV)/.installed-ros: pyproject.toml $(ROS_MSGS) | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[ros]'
	ros/build_msgs.sh $(VENV)
	touch $@

ros: $(VENV)/.installed-ros

# The F1TENTH gym v1.0.0 (on no index) for rkmpc.envs.f1tenth_gym and its tests: the f1tenth-gym extra (its
# dependencies pinned, OpenCV's headless build), then the gym from ../shared/vendor without its declared
# dependencies (they name opencv-python, a GUI build that needs libGL). The tests install it when the
# tarball is there; without it the tests that drive the gym skip.
F1TENTH_GYM_TARBALL := ../shared/vendor/f1tenth_gym-1.0.0.tar.gz
$(VENV)/.installed-f1tenth-gym: pyproject.toml $(F1TENTH_GYM_TARBALL) | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[f1tenth-gym]'
	$(BIN)/python -m pip install --quiet --no-deps --force-reinstall $(F1TENTH_GYM_TARBALL)
	touch $@
F1TENTH_GYM_FOR_TESTS := $(if $(wildcard $(F1TENTH_GYM_TARBALL)),$(VENV)/.installed-f1tenth-gym)

f1tenth-gym: $(VENV)/.installed-f1tenth-gym

# The paper's on-car workflow over ROS 2 on this machine (docs/car.md): two LMPC laps recorded to a
# bag by the node, the residual and identified models trained from it, LMPC, lmpc-id and RKMPC a lap
# each, then 50 ms of added actuation delay with and without compensation. Table II: runs/car-loop/table2.md.
car-loop: $(VENV)/.installed $(VENV)/.installed-ros
	$(BIN)/rkmpc car-loop --out runs/car-loop --force

# The paper's Table I on the built-in track: two LMPC laps of data, the residual models and
# lmpc-id learned from them, the KMPC model (trained once, then cached), then every controller.
demo: $(VENV)/.installed
	$(BIN)/rkmpc compare --track builtin --out runs/demo --force

# The paper's point in under a minute: the LMPC, lmpc-id and rkmpc from the same two LMPC laps
# (no KMPC model to train, no nonlinear MPC to drive).
demo-quick: $(VENV)/.installed
	$(BIN)/rkmpc compare --track builtin --controllers lmpc,lmpc-id,rkmpc --out runs/demo-quick --force

# The fast tier, on two pytest workers (under 4 minutes on two quiet cores); `make test-slow` runs the
# long end-to-end tests, one at a time.
test: $(VENV)/.installed-test $(VENV)/.installed-acados $(VENV)/.installed-ros $(F1TENTH_GYM_FOR_TESTS)
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/ruff format --check src tests benchmarks
	$(BIN)/mypy
	$(BIN)/python -m pytest -m "not slow" -n 2 --dist loadfile

test-slow: $(VENV)/.installed-test $(VENV)/.installed-acados $(VENV)/.installed-ros $(F1TENTH_GYM_FOR_TESTS)
	$(BIN)/python -m pytest -m slow

test-all: test test-slow

bench: $(VENV)/.installed $(VENV)/.installed-acados
	$(BIN)/python benchmarks/bench_step.py --out runs/bench/step_times.json
	$(BIN)/python benchmarks/bench_estimator.py --out runs/bench/estimator.json

# Where the time of one RKMPC step goes, stage by stage.
bench-breakdown: $(VENV)/.installed
	$(BIN)/python benchmarks/bench_breakdown.py --out runs/bench/breakdown.json

tracks-table: $(VENV)/.installed
	$(BIN)/python benchmarks/tracks_table.py --out runs/tracks

# Every controller on the built-in and every shared track (runs in parallel on the local cores).
study-tracks: $(VENV)/.installed
	$(BIN)/rkmpc study tracks --tracks builtin,../shared/tracks/centerlines --out runs/study-tracks --force

# Every controller on six cars of the zoo (issue 11) over every shared track, through the real F1TENTH
# car's sensors (the study's default; docs/cars.md); 45-60 minutes on 2 cores with a warm model cache.
study-cars: $(VENV)/.installed
	$(BIN)/rkmpc study cars --cars gym,overshoot,cheap-servo,low-grip,heavy-long,light-short \
		--tracks builtin,../shared/tracks/centerlines --controllers pp,lmpc,lmpc-id,rkmpc --out runs/study-cars --force

# Race pace (issue 14): each controller up the pace ladder on the built-in and every shared track;
# about 5 hours on 2 cores, resumable: a stopped run picks up from runs/study-pace-journal.
study-pace: $(VENV)/.installed
	$(BIN)/rkmpc study pace --tracks builtin,../shared/tracks/centerlines \
		--controllers lmpc,lmpc-id,rkmpc,nmpc-dynamic --journal runs/study-pace-journal --out runs/study-pace --force

# The full-size car (issue 11) on every shared track.
study-fullsize: $(VENV)/.installed
	$(BIN)/rkmpc study tracks --vehicle fullsize --tracks ../shared/tracks/centerlines \
		--controllers lmpc,lmpc-id,rkmpc --journal runs/study-fullsize-journal --out runs/study-fullsize --force

# RKMPC against KMPC as the training data grow, three seeds.
study-data: $(VENV)/.installed
	$(BIN)/rkmpc study data --track builtin --out runs/study-data --force

# What each fault does to every controller on the built-in track (models come from the cache).
FAULTS := noise delay friction heavy
faults: $(VENV)/.installed
	for f in $(FAULTS); do $(BIN)/rkmpc compare --track builtin --fault $$f --out runs/faults/$$f --force || exit 1; done

# docs/results.md from a full run: demo, faults, both studies and the step-time benchmark.
results: demo faults study-tracks study-data bench
	$(BIN)/python benchmarks/results_doc.py --demo runs/demo --faults runs/faults --tracks runs/study-tracks \
		--data runs/study-data --bench runs/bench/step_times.json --notes docs/results-notes.md --out docs/results.md

clean:
	rm -rf runs .pytest_cache .mypy_cache .ruff_cache
