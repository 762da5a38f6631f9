# Set-up and everyday commands. Only python3 (3.11+) is needed on the machine.
PYTHON ?= python3
VENV   := .venv
BIN    := $(VENV)/bin

.PHONY: demo test lint bench tracks-table learning-table clean

# PyTorch first and pinned exactly: a looser pin pulls a multi-gigabyte CUDA build.
$(BIN)/python:
	$(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade pip
	$(BIN)/python -m pip install --quiet torch==2.13.0

$(VENV)/.installed: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e .
	touch $@

$(VENV)/.installed-test: pyproject.toml | $(BIN)/python
	$(BIN)/python -m pip install --quiet -e '.[test]'
	touch $@ $(VENV)/.installed

# Two LMPC laps of data, the residual model and lmpc-id learned from them, then every controller.
demo: $(VENV)/.installed
	$(BIN)/rkmpc collect --controller lmpc --laps 2 --track builtin --out runs/demo/data.npz
	$(BIN)/rkmpc train --data runs/demo/data.npz --kind residual --out runs/demo/residual.rkm
	$(BIN)/rkmpc train --data runs/demo/data.npz --kind identified --out runs/demo/identified.json
	$(BIN)/rkmpc compare --track builtin --controllers pp,lmpc,lmpc-id,rkmpc \
		--model rkmpc=runs/demo/residual.rkm --model lmpc-id=runs/demo/identified.json --out runs/demo

test: $(VENV)/.installed-test
	$(BIN)/ruff check src tests benchmarks
	$(BIN)/mypy
	$(BIN)/python -m pytest

bench: $(VENV)/.installed
	$(BIN)/python benchmarks/bench_step.py --out runs/bench/step_times.json $(if $(wildcard runs/learning/kmpc_50000_0.rkm),--kmpc-model runs/learning/kmpc_50000_0.rkm)

tracks-table: $(VENV)/.installed
	$(BIN)/python benchmarks/tracks_table.py --out runs/tracks

learning-table: $(VENV)/.installed
	$(BIN)/python benchmarks/learning_table.py --out runs/learning

clean:
	rm -rf runs .pytest_cache .mypy_cache .ruff_cache
