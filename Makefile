# ros_hrc: `make run` sets up (if needed), builds and starts the whole stack;
# `make test` sets up (if needed), builds and runs every test.
SHELL := /bin/bash
ARGS ?=

.PHONY: setup run test unit rostest bench experiment fit lint clean

setup:
	@bash tools/setup.sh

run: setup
	@source env.sh && roslaunch ros_hrc hrc.launch $(ARGS)

test: setup
	@bash tools/run_tests.sh

unit: setup
	@source env.sh && python -m pytest test/unit -q

bench: setup
	@source env.sh && python bench/run_all.py $(ARGS)

# A small default grid (README, "Experiments"); ARGS="--episodes 10 --seeds 0,1,2" for more.
experiment: setup
	@source env.sh && rosrun ros_hrc hrc_experiment --out results/experiment $(ARGS)

# Fit the robot model's T and O to the world (docs/fitting.md); rewrites models/robot/robot_fitted.pomdp.
fit: setup
	@source env.sh && rosrun ros_hrc hrc_fit --out models/robot/robot_fitted.pomdp $(ARGS)

lint: setup
	@source env.sh && catkin_lint --strict -W2 .ws/src/ros_hrc

clean:
	rm -rf .ws .venv
