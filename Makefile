# Set-up and everyday commands. `make run` and `make test` each build the
# virtual environment on first use (and reinstall when the sources change).

PYTHON ?= python3
VENV ?= .venv
BIN := $(VENV)/bin
STAMP := $(VENV)/.installed
# Present after `make dev`: every (re)install is then editable, so edits to the sources
# take effect without reinstalling.
EDITABLE := $(VENV)/.editable
# The mode of the last install; a change of mode (make dev, or removing .editable) reinstalls.
MODE_STAMP := $(VENV)/.mode-$(if $(wildcard $(EDITABLE)),editable,normal)
# The exact versions the suite last passed with (`make lock` writes it; setup.py keeps the
# compatible ranges that users install within).
CONSTRAINTS := constraints.txt
EXTRAS := ros,plots,study,test
# The lock pins every extra, those `make install` leaves out (serial) too.
LOCK_EXTRAS := $(EXTRAS),serial
SOURCES := setup.py setup.cfg package.xml $(CONSTRAINTS) $(wildcard config/*.yaml launch/*.py rviz/*.rviz) \
           $(wildcard uav_comm_planner/*.py uav_comm_planner/*/*.py) resource/uav_comm_planner

# One DDS domain per run, discovery on this machine only, so that test runs
# and planners on a shared machine do not hear each other.
comma := ,
ROS_ENV := ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST AMENT_PREFIX_PATH=$(abspath $(VENV))

.PHONY: install dev run test test-latest lock fuzz bench figures docs airframe clean

install: $(STAMP)

$(MODE_STAMP):
	mkdir -p $(VENV)
	rm -f $(VENV)/.mode-*
	touch $@

$(STAMP): $(SOURCES) $(MODE_STAMP)
	@echo 'Installing the package and its dependencies into $(VENV): minutes the first time...'
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	$(BIN)/python -m pip install --quiet --upgrade 'pip>=23,<27'
	$(BIN)/python -m pip install --quiet --constraint $(CONSTRAINTS) $(if $(wildcard $(EDITABLE)),--editable )'.[$(EXTRAS)]'
	@# `ros2 run uav_comm_planner planner` looks for lib/<package>/<executable>;
	@# pip puts console scripts in bin/, so link them where ros2 run looks.
	mkdir -p $(VENV)/lib/uav_comm_planner
	for exe in planner send_ground_nodes uav-comm-planner; do \
		ln -sf ../../bin/$$exe $(VENV)/lib/uav_comm_planner/$$exe; done
	@# An editable install leaves out setup.py's data_files (the ament index marker, package.xml,
	@# config, launch, rviz): copy them where a normal install puts them.
	if test -e $(EDITABLE); then \
		mkdir -p $(VENV)/share/ament_index/resource_index/packages $(VENV)/share/uav_comm_planner && \
		cp resource/uav_comm_planner $(VENV)/share/ament_index/resource_index/packages/ && \
		cp -r package.xml config launch rviz $(VENV)/share/uav_comm_planner/; fi
	touch $(STAMP)

# Editable install: the commands and imports run the checkout's sources, not a copy.
# `rm .venv/.editable && make install` (or `make clean`) goes back to a normal install.
dev:
	test -x $(BIN)/python || $(PYTHON) -m venv $(VENV)
	touch $(EDITABLE)
	$(MAKE) install

run: $(STAMP)
	$(ROS_ENV) ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-0} $(BIN)/planner $(ARGS)

test: $(STAMP)
	$(ROS_ENV) ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-$$(( 100 + $$$$ % 100 ))} \
		$(BIN)/python -m pytest $(PYTEST_ARGS)

# The suite on the newest versions that setup.py's ranges allow, in a venv of its own (not in
# CI): a release that breaks the package is found on purpose, here, not by a new user.
LATEST_VENV ?= .venv-latest
test-latest:
	rm -rf $(LATEST_VENV)
	$(PYTHON) -m venv $(LATEST_VENV)
	$(LATEST_VENV)/bin/python -m pip install --quiet --upgrade 'pip>=23,<27'
	$(LATEST_VENV)/bin/python -m pip install --quiet --upgrade --upgrade-strategy eager \
		'.[$(EXTRAS)]'
	mkdir -p $(LATEST_VENV)/lib/uav_comm_planner
	for exe in planner send_ground_nodes uav-comm-planner; do \
		ln -sf ../../bin/$$exe $(LATEST_VENV)/lib/uav_comm_planner/$$exe; done
	$(LATEST_VENV)/bin/python -m pip freeze --exclude-editable
	ROS_AUTOMATIC_DISCOVERY_RANGE=LOCALHOST AMENT_PREFIX_PATH=$(abspath $(LATEST_VENV)) \
		ROS_DOMAIN_ID=$${ROS_DOMAIN_ID:-$$(( 100 + $$$$ % 100 ))} \
		$(LATEST_VENV)/bin/python -m pytest $(PYTEST_ARGS)

# Writes $(CONSTRAINTS) anew with uv's resolver (newest versions within setup.py's ranges,
# keeping those already pinned where they still fit); then run `make test` before committing it.
lock: $(STAMP)
	$(BIN)/python -m pip install --quiet 'uv>=0.9,<1'
	$(BIN)/uv pip compile setup.py $(foreach e,$(subst $(comma), ,$(LOCK_EXTRAS)),--extra $(e)) \
		--python-version 3.11 --output-file $(CONSTRAINTS)

# Seeded fuzzing of the API, the command line and mission export, then of the vehicle link
# against a fake vehicle on 127.0.0.1, then of zones and fence files, then of vehicle parameter
# files, study designs and hand-edited study tables (minutes each; short runs of the last three
# are in `test`).
FUZZ_CASES ?= 10000
FUZZ_SEED ?= 1
fuzz: $(STAMP)
	$(BIN)/python test/fuzz/fuzz_api_cli.py --cases $(FUZZ_CASES) --seed $(FUZZ_SEED)
	$(BIN)/python test/fuzz/fuzz_vehicle.py --cases $(FUZZ_CASES) --seed $(FUZZ_SEED)
	$(BIN)/python test/fuzz/fuzz_zones.py --cases $(FUZZ_CASES) --seed $(FUZZ_SEED)
	$(BIN)/python test/fuzz/fuzz_inputs.py --cases $(FUZZ_CASES) --seed $(FUZZ_SEED)

# The benchmark, from devtools/ (not installed). Its flight section flies on ArduCopter SITL:
# $(SITL), or $$UAV_COMM_PLANNER_SITL if unset.
SITL ?= $(wildcard ../shared/sitl/arducopter)

bench: $(STAMP)
	$(BIN)/python -m devtools.bench $(if $(SITL),--sitl $(SITL)) $(ARGS)

figures: $(STAMP)
	mkdir -p docs
	$(BIN)/uav-comm-planner plan --case I --figure docs/fig1_case_I.png
	$(BIN)/uav-comm-planner plan --case II --figure docs/fig1_case_II.png
	$(BIN)/uav-comm-planner sweep --case I --budgets 0.5,1,2,5,10,20 --figure docs/fig2_sweep_case_I.png
	$(BIN)/uav-comm-planner sweep --case II --budgets 0.5,1,2,5,10,20 --figure docs/fig2_sweep_case_II.png
	$(BIN)/uav-comm-planner plan --case I --bandwidth 1e6 --beta0 1e-6 --budget 0.5 \
		--figure docs/fig1_case_I_low_snr.png
	$(BIN)/uav-comm-planner energy-sweep --case I --speed 30 --horizon 200 --airframe zeng2019 \
		--figure docs/fig_energy_tradeoff_case_I.png
	$(BIN)/uav-comm-planner plan --uavs 2 --start "0,0;0,500" --goal "2000,0;2000,500" \
		--min-separation 100 --figure docs/fleet_case_I.png
	$(BIN)/python -m devtools.shared_band_study --figure docs/fleet_shared_band.png

# The parameter tables of docs/node.md, from the node's own parameter descriptors
# (devtools/docgen.py, not installed).
docs: $(STAMP)
	$(BIN)/python -m devtools.docgen docs/node.md

# ArduCopter SITL's default quad measured (about 2 minutes at its speed-up): flies it, writes
# the samples' CSV, the fitted airframe (vehicle/airframes/arducopter_sitl_quad.*) and the
# fit-airframe tests' tlog (test/data/), and prints the measured table.
airframe: $(STAMP)
	$(BIN)/python -m devtools.measure_airframe $(if $(SITL),--sitl $(SITL)) $(ARGS)

clean:
	rm -rf $(VENV) $(LATEST_VENV) build *.egg-info
