# ros_hrc: `make run` sets up (if needed), builds and starts the whole stack;
# `make test` sets up (if needed), builds and runs every test.
SHELL := /bin/bash
, := ,
ARGS ?=

.PHONY: setup run test unit rostest bench experiment fit fit-types train-selector lint clean

setup:
	@bash tools/setup.sh

# roslaunch as the terminal's foreground job (tools/foreground.py): Ctrl-C reaches it alone,
# and `make run` ends with its status (0), not make's own 130 for an interrupt.
run: setup
	@source env.sh && python3 tools/foreground.py roslaunch ros_hrc hrc.launch $(ARGS)

test: setup
	@bash tools/run_tests.sh

unit: setup
	@bash tools/run_tests.sh unit

rostest: setup
	@bash tools/run_tests.sh rostest

bench: setup
	@source env.sh && python bench/run_all.py $(ARGS)

# The study (docs/experiments.md): the held-out humans, the anticipating robots against the
# reactive one tuned over budgets 1..10 and the human alone, 92 episodes per cell (a 15-point
# difference in success detectable). ARGS="--episodes 30" for a quicker, weaker look.
# ARGS="--task fabric": the successor task's study instead (its ten human types; the human
# alone, the reactive MDP robot with its wait swept over 5..30 simulated seconds, the
# proactive POMDP robot), into results/experiment_fabric.
# ARGS="--task fabric --sequence 30": the sequence study instead (issue #30: the selectors
# over the task's library, 5 sequences per cell), into results/sequences_fabric
# (results/sequences without --task fabric); docs/experiments.md, "Sequences".
EXPERIMENT_POLICIES ?= pomdp,pomdp_fitted,pomdp_considerate,no_robot
FABRIC_STUDY := $(or $(findstring --task fabric,$(ARGS)),$(findstring --task=fabric,$(ARGS)))
SEQUENCE_STUDY := $(findstring --sequence,$(ARGS))
experiment: setup
	@source env.sh && rosrun ros_hrc hrc_experiment \
	    $(if $(SEQUENCE_STUDY),--out results/sequences$(if $(FABRIC_STUDY),_fabric),\
	    $(if $(FABRIC_STUDY),--out results/experiment_fabric --reactive-budgets 5$(,)10$(,)20$(,)30,\
	         --out results/experiment --policies $(EXPERIMENT_POLICIES) --reactive-budgets 1..10)) \
	    $(ARGS)

# Fit the robot models' T and O to the world on the zoo's fit set (docs/robot_model.md):
# rewrites models/robot/robot_fitted.pomdp (the authors' rewards) and
# robot_considerate_fitted.pomdp (the considerate rewards); both fits share one set of episodes.
fit: setup
	@source env.sh && rosrun ros_hrc hrc_fit --out models/robot/robot_fitted.pomdp $(ARGS) \
	    && rosrun ros_hrc hrc_fit --prior robot_considerate \
	       --out models/robot/robot_considerate_fitted.pomdp $(ARGS) \
	    && rosrun ros_hrc hrc_fit --prior robot_considerate --rewards utility \
	       --out models/robot/robot_utility_fitted.pomdp $(ARGS)

# A robot model of human types (issue #31, docs/robot_model.md): T and O fitted per human model
# of the fit set, each a type, on make fit's episodes (results/fit: reused), composed into one
# POMDP whose hidden state is (type, state): models/robot/robot_types.pomdp (the considerate
# rewards). ARGS="--task fabric": fabric's ten types with the authors' base, on
# results/fit_fabric, into models/fabric/robot/robot_types.pomdp.
fit-types: setup
	@source env.sh && rosrun ros_hrc hrc_fit --types $(if $(FABRIC_STUDY),,--prior robot_considerate) \
	    $(ARGS)

# Train the selector's model from our own runs (docs/experiments.md, "hrc_train_selector"):
# every (type, policy) pair of the task's library plays 50 tasks through the real stack on
# the trainer's seed (4, not the study's 2), into results/train_selector_<task>, then
# models/<task>/selector_model.json. ARGS="--task fabric" for FABRIC's (the default task is
# the seed's); ARGS="--leave-out TYPE" writes a model without TYPE beside it. The shipped
# models were trained with fewer tasks (their headers name the command): fabric's with
# ARGS="--task fabric --tasks-per-pair 20 --max-trials 100", the seed's with
# ARGS="--tasks-per-pair 20" (docs/study/sequences.md).
train-selector: setup
	@source env.sh && rosrun ros_hrc hrc_train_selector $(ARGS)

lint: setup
	@source env.sh && catkin_lint --strict -W2 .ws/src/ros_hrc && PYTHONPATH=src:$$PYTHONPATH lint-imports --no-logo

clean:
	rm -rf .ws .venv
