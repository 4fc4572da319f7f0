# Quick start targets. Each creates .venv (Python 3.12) and installs the project if needed.
PY ?= $(shell for p in python3.12 /root/.pyenv/versions/3.12*/bin/python3.12 /usr/bin/python3.12; do $$p -c pass 2>/dev/null && { echo $$p; break; }; done)
VENV := .venv
STAMP := $(VENV)/.installed

# Upgrade check: a separate venv installed WITHOUT constraints.txt (whatever resolves today), then a
# short test selection. tests/test_pinned_env.py there lists what moved (expected to differ).
UPVENV := .venv-upgrade
UPGRADE_TESTS ?= tests/stages/test_simulate_robot.py tests/stages/test_simulate_manipulation.py \
	tests/stages/test_dataset_schema.py tests/stages/test_dataset_shards.py tests/stages/test_physics_checks.py

.PHONY: demo test install bench upgrade-check

# Installs exactly the versions in constraints.txt (what CI tests with).
$(STAMP): pyproject.toml constraints.txt
	@test -x $(VENV)/bin/python || $(PY) -m venv $(VENV)
	$(VENV)/bin/python -m pip install -q --upgrade pip
	$(VENV)/bin/python -m pip install -q -c constraints.txt -e '.[test]'
	@# the teleop page's headset emulator (IWER) from the npm registry; without npm its test skips
	-$(VENV)/bin/python -m stages.teleop.vendor
	@touch $(STAMP)

install: $(STAMP)

demo: $(STAMP)
	$(VENV)/bin/agentworld run jobs/main.toml

test: $(STAMP)
	$(VENV)/bin/python -m pytest -q tests

bench: $(STAMP)
	$(VENV)/bin/python -m pytest -q -m benchmark tests/benchmarks -s

upgrade-check:
	rm -rf $(UPVENV)
	$(PY) -m venv $(UPVENV)
	$(UPVENV)/bin/python -m pip install -q --upgrade pip
	$(UPVENV)/bin/python -m pip install -q --upgrade -e '.[test]'
	@echo "--- versions that differ from constraints.txt (expected in an upgrade):"
	-$(UPVENV)/bin/python -m pytest -q --no-header -p no:cacheprovider tests/test_pinned_env.py -k installed_distributions
	@echo "--- tests on the unpinned versions:"
	$(UPVENV)/bin/python -m pytest -q -p no:cacheprovider $(UPGRADE_TESTS)
