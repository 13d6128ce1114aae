# physlab — `make lab` opens the lessons, `make test` runs everything. Both set up .venv first.
#
# Override on the command line, e.g.
#   make test TORCH_SPEC="torch --index-url https://download.pytorch.org/whl/cpu"
#   make lab  TORCH_SPEC="torch --index-url https://download.pytorch.org/whl/cu124"
PYTHON     ?= python3
VENV       ?= .venv
# The CPU build of PyTorch that these machines carry on local disk (an unpinned `torch`
# would download several GB of CUDA libraries).
TORCH_SPEC ?= torch==2.13.0
EXTRAS     ?= all
PYTEST_ARGS ?=
# pytest-xdist workers for the three test stages (0 = run in this process, one test at a time).
TEST_WORKERS ?= 2
LAB_ARGS   ?=

BIN   := $(VENV)/bin
PY    := $(BIN)/python
STAMP := $(VENV)/.physlab-installed

.PHONY: help venv lab test test-unit test-lessons test-e2e browser reproduce bench motion-model motion-model-quick motion-evaluator lesson-data clean distclean

help:
	@echo "make lab        set up .venv and open JupyterLab on lessons/"
	@echo "make test       set up .venv and run the whole suite (unit tests, executed lessons, browser test)"
	@echo "make reproduce  execute every lesson headless, write figures to reports/"
	@echo "make bench      run the benchmarks in benchmarks/"
	@echo "make motion-model  retrain the shipped motion checkpoints in data/motion/ (2 cores; time: data/motion/README.md)"
	@echo "make motion-model-quick  issue 12's four motion models in about 90 min, into runs/quick/, and their evaluation"

# (Re)install whenever pyproject.toml changes.
$(STAMP): pyproject.toml
	@test -x $(PY) || $(PYTHON) -m venv $(VENV)
	$(PY) -m pip install --quiet --upgrade pip setuptools wheel
	$(PY) -m pip install --quiet $(TORCH_SPEC)
	$(PY) -m pip install --quiet -e ".[$(EXTRAS)]"
	@touch $(STAMP)

venv: $(STAMP)

# The browser test drives JupyterLab in the system Chromium; install it when we can (root + apt).
browser:
	@if command -v chromium >/dev/null 2>&1; then :; \
	elif [ "$$(id -u)" = 0 ] && command -v apt-get >/dev/null 2>&1; then \
		echo "installing Debian chromium for the browser test"; \
		(apt-get update -qq && DEBIAN_FRONTEND=noninteractive apt-get install -y -qq chromium >/dev/null) \
		|| echo "could not install chromium; the browser test will be skipped"; \
	else echo "no chromium and no root apt: the browser test will be skipped"; fi

lab: $(STAMP)
	$(BIN)/jupyter lab --notebook-dir=lessons $(if $(filter 0,$(shell id -u)),--allow-root) $(LAB_ARGS)

test-unit: $(STAMP)
	$(PY) -m pytest tests -m "not e2e" -n $(TEST_WORKERS) --dist loadgroup $(PYTEST_ARGS)

# The lessons run against an empty external-data folder: they must work on a clone without
# ../shared/data (lesson 09 uses the windows shipped in data/motion/). Each lesson runs whole on
# one worker (--dist loadfile): its cells share one kernel, in order.
test-lessons: $(STAMP)
	@empty=$$(mktemp -d); \
	PHYSLAB_EXTERNAL_DATA=$$empty $(PY) -m pytest --nbval-lax --nbval-current-env \
		--nbval-cell-timeout=300 -n $(TEST_WORKERS) --dist loadfile lessons $(PYTEST_ARGS); rc=$$?; rm -rf "$$empty"; exit $$rc

test-e2e: $(STAMP) browser
	$(PY) -m pytest tests -m e2e -n $(TEST_WORKERS) --dist worksteal $(PYTEST_ARGS)

# All three stages run even when one fails, so a flaky lesson cannot hide a broken browser
# test; the last line names every failed stage. (pytest exits 5 when it collects nothing.)
test: $(STAMP) browser
	@failed=""; \
	$(MAKE) --no-print-directory test-unit    || failed="$$failed unit"; \
	$(MAKE) --no-print-directory test-lessons || failed="$$failed lessons"; \
	$(MAKE) --no-print-directory test-e2e     || failed="$$failed browser"; \
	if [ -n "$$failed" ]; then echo "make test: FAILED stage(s):$$failed"; exit 1; fi; \
	echo "make test: unit tests, lessons and browser tests all passed"

reproduce: $(STAMP)
	$(PY) -m physlab.cli reproduce --out reports

bench: $(STAMP)
	$(PY) benchmarks/run_all.py

# Retrains data/motion/*.pt (part 4, Sketch2Anim) from the Bandai-Namco clips in ../shared/data
# (every take but the held-out 002) on 2 cores: the text-motion evaluator (1000 steps, one
# thread), the text-conditioned base denoiser (10000 steps), the trajectory ControlNet + keypose
# adapter on the frozen base (12000 steps; 6000 gave 0.101 / 0.038 m instead of 0.081 / 0.033 m
# networks-only trajectory / pose error, README), continued twice by 3000 steps with the keypose
# term of Eq. 9 weighted 10x (--lambda-key 10; each continuation a warm restart of the cosine:
# networks-only pose error 0.032 -> 0.028 m, 2.8x -> 3.2x below text only, README), and the
# single-ControlNet ablation (12000 steps, the adapter's budget before the keypose
# continuations, for Table 2), then the 2D encoders aligned to the 3D ones (align stage:
# 10000 steps of Eq. 13, then continued to 15000 on the same checkpoint, a warm restart of the
# cosine, with the drawn trajectories' 2D error as an extra term, --lambda-tr-2d 8: networks-only
# Average protocol 1.85x -> 2.07x text only, README) and the lift-and-control lifter.
# Timed 2026-11-27/28 on the 2-core host on a fast day (runs/s32, runs/s34; the host varies up
# to 2x from day to day): evaluator 4.3 min, base 8.4, control 34.0 + 16.7 for the two keypose
# continuations, single ControlNet 21.6 - issue 12's models in 85 min - then align 45-47 min
# (330-354 windows/s), the lifter about 10 min and the text base 21.5 min (20,000 steps,
# 2026-12-02): about 2 h 45 min in all. On a 2-core
# AVX2-only EPYC without AVX512-BF16 (2026-11-28; fp32 via MOTION_PRECISION=auto) the base
# stage ran at 225 windows/s and the control stage at 88: the retrain takes 3-4x as long.
# Resumable: rerun after an interruption (Ctrl-C or `kill` writes a checkpoint).
# The text base (EDM skip connection on the pose, action-balanced, 4x velocity loss) samples
# text-only requests; it is attached to the exported control checkpoint (physlab.motion.
# checkpoint.attach_text_model; data/motion/README.md says why).
# Full-precision checkpoints stay in $(MOTION_RUNS); $(MOTION_EXPORT) gets the fp16 inference
# copies (set MOTION_EXPORT=runs/x to retrain beside the shipped models and compare).
# MOTION_PRECISION=auto (default) runs the forward passes in bfloat16 autocast (weights,
# optimiser and checkpoints stay float32) where the CPU has native bfloat16 (AVX512-BF16 or
# AMX): 1.24x (base) / 1.36x (control) the float32 throughput on such a host
# (benchmarks/bench_motion.py); elsewhere fp32, because emulated bf16 is far slower (~15x
# for the base stage on a 2-core AVX2 EPYC, 2026-11-28). MOTION_PRECISION=bf16 / fp32 force
# one. The files shipped before 2026-11-27 were trained in fp32; the bf16 retrain shipped
# since scores within noise of them (README).
MOTION_RUNS      ?= runs/motion
MOTION_EXPORT    ?= data/motion
MOTION_PRECISION ?= auto
MOTION_TRAIN := $(PY) -m physlab.motion.train --num-threads 2 --precision $(MOTION_PRECISION) \
	--text-cache $(MOTION_RUNS)/text_cache.npz
motion-evaluator: $(STAMP)
	mkdir -p $(MOTION_RUNS) $(MOTION_EXPORT)
	$(PY) -m physlab.motion.evaluator train --num-threads 1 --steps 1000 \
		--text-cache $(MOTION_RUNS)/text_cache.npz --out $(MOTION_RUNS)/evaluator.pt \
		--export $(MOTION_EXPORT)/text_motion_evaluator.pt

motion-model: $(STAMP) motion-evaluator
	$(MOTION_TRAIN) --stage base --steps 10000 --out $(MOTION_RUNS)/base.pt
	$(MOTION_TRAIN) --stage control --steps 12000 --base-ckpt $(MOTION_RUNS)/base.pt \
		--out $(MOTION_RUNS)/control.pt
	$(MOTION_TRAIN) --stage control --steps 15000 --lambda-key 10 --base-ckpt $(MOTION_RUNS)/base.pt \
		--out $(MOTION_RUNS)/control.pt
	$(MOTION_TRAIN) --stage control --steps 18000 --lambda-key 10 --base-ckpt $(MOTION_RUNS)/base.pt \
		--out $(MOTION_RUNS)/control.pt --export $(MOTION_EXPORT)/sketch2anim_control.pt
	$(MOTION_TRAIN) --stage control --single-controlnet --steps 12000 \
		--base-ckpt $(MOTION_RUNS)/base.pt --out $(MOTION_RUNS)/single_controlnet.pt \
		--export $(MOTION_EXPORT)/sketch2anim_single_controlnet.pt
	$(MOTION_TRAIN) --stage align --steps 10000 --single-joint 0.25 \
		--base-ckpt $(MOTION_RUNS)/control.pt --out $(MOTION_RUNS)/align.pt
	$(MOTION_TRAIN) --stage align --steps 15000 --single-joint 0.25 --lambda-tr-2d 8 \
		--base-ckpt $(MOTION_RUNS)/control.pt \
		--out $(MOTION_RUNS)/align.pt --export $(MOTION_EXPORT)/sketch2anim_control.pt
	$(MOTION_TRAIN) --stage base --steps 20000 --skip --no-skip-pelvis --snr-cap 10 \
		--balance 0.5 --lambda-vel 4 --style-drop 0.3 --pelvis-scale 5 --seed 1 \
		--out $(MOTION_RUNS)/text_base.pt
	$(PY) -m physlab.motion.checkpoint attach-text $(MOTION_EXPORT)/sketch2anim_control.pt \
		$(MOTION_RUNS)/text_base.pt --guidance 6,4.5
	$(PY) -m physlab.motion.baselines train-lifter --steps 3000 --num-threads 2 \
		--out $(MOTION_RUNS)/lifter.pt --export $(MOTION_EXPORT)/sketch_lifter.pt

# Issue 12's four models in 90 min on 2 cores, into $(MOTION_QUICK) (not data/motion: the
# export carries no 2D encoders, lifter or text base), then their held-out evaluation (64
# windows; networks only, guided, single ControlNet): motion-model's evaluator and base, its
# control stage cut to 6000 steps without the keypose continuations, the single ControlNet
# at the same 6000. Times and numbers (and why not a quarter of every stage): README,
# "Retraining in 90 min".
MOTION_QUICK ?= runs/quick
MOTION_QUICK_TRAIN := $(PY) -m physlab.motion.train --num-threads 2 --precision $(MOTION_PRECISION) \
	--text-cache $(MOTION_QUICK)/text_cache.npz
motion-model-quick: $(STAMP)
	mkdir -p $(MOTION_QUICK)/export
	$(PY) -m physlab.motion.evaluator train --num-threads 1 --steps 1000 \
		--text-cache $(MOTION_QUICK)/text_cache.npz --out $(MOTION_QUICK)/evaluator.pt \
		--export $(MOTION_QUICK)/export/text_motion_evaluator.pt
	$(MOTION_QUICK_TRAIN) --stage base --steps 10000 --out $(MOTION_QUICK)/base.pt
	$(MOTION_QUICK_TRAIN) --stage control --steps 6000 --base-ckpt $(MOTION_QUICK)/base.pt \
		--out $(MOTION_QUICK)/control.pt --export $(MOTION_QUICK)/export/sketch2anim_control.pt
	$(MOTION_QUICK_TRAIN) --stage control --single-controlnet --steps 6000 \
		--base-ckpt $(MOTION_QUICK)/base.pt --out $(MOTION_QUICK)/single_controlnet.pt \
		--export $(MOTION_QUICK)/export/sketch2anim_single_controlnet.pt
	$(PY) -m physlab.motion.evaluate --control $(MOTION_QUICK)/export/sketch2anim_control.pt \
		--single-controlnet $(MOTION_QUICK)/export/sketch2anim_single_controlnet.pt \
		--evaluator $(MOTION_QUICK)/export/text_motion_evaluator.pt \
		--windows 64 --num-threads 2 --out $(MOTION_QUICK)/eval

# Rebuilds data/motion/lesson_windows.npz (the real windows lesson 09 shows, so that it runs
# without ../shared/data) from the Bandai-Namco clips.
lesson-data: $(STAMP)
	$(PY) -c "from physlab.demos.motion_diffusion import write_lesson_windows as w; print(w())"

clean:
	rm -rf reports .pytest_cache
	find . -name __pycache__ -not -path "./.venv/*" -prune -exec rm -rf {} +

distclean: clean
	rm -rf $(VENV)
