# The one entry point. A newcomer types `make demo` and `make test`; everything else is below.
#   make deps            install Debian packages + project venv (idempotent)
#   make build           host C++ build (build/), sanitizer build of protocol/ (build-asan/), firmware image
#   make test            deps + build, then every test suite (ctest, ASan ctest, fuzz smoke, pytest)
#   make demo            deps + build, then the end-to-end demo of what exists
#   make data            download the TUM sequences (SEQ="fr1_xyz ...", default: every pinned one),
#                        check size + sha256, cut the bench excerpts into data/tum (docs/data.md)
#   make bench           accuracy/speed benchmarks on DATA (default ../shared/data, else data/tum)
#   make study           the frame-rate / spatial-velocity study on DATA
#   make results         docs/results.md from out/results/*.json (written by bench, hil, demo-loop)
#   make fuzz            longer libFuzzer runs (FUZZ_SECONDS per target, default 300)
#   make hil             all hardware-in-loop scenarios
#   make wind-table      HIL hold against gust strength for both position laws -> out/results/wind.json
#   make soak            HIL missions back to back for SOAK_MINUTES (60) under a seeded fault schedule
#                        (SOAK_SEED), then a report in out/soak/ and a replay check (docs/hil.md, Soak)
#   make firmware        build the ATmega328P image, print flash/RAM use
#   make flash PORT=/dev/ttyACM0   upload the firmware with avrdude
#   make install-onboard install rgbd-streamer + config + systemd unit on this (onboard) machine (.deb)
#   make onboard-arm ARCH=arm64|armhf  cross-build rgbd-streamer + unit tests (build-ARCH/), .deb;
#                        TEST=1 also runs them under qemu-user; make bench-arm: encode cost on ARM
#   make run-offboard    start the ground station for real hardware
#   make clean           remove build outputs (keeps .venv)
SHELL := /bin/bash
JOBS ?= $(shell nproc)
DATA ?= $(shell scripts/data-dir.sh)
PORT ?= /dev/ttyACM0
FUZZ_SECONDS ?= 300
ARCH ?= arm64
export DATA JOBS PORT FUZZ_SECONDS

# $(call component,script,args): run a component's entry script, or say it is not implemented yet.
define component
	@if [ -x "$(1)" ]; then "$(1)" $(2); else echo "make $@: not implemented yet ($(1) does not exist)"; exit 1; fi
endef

.PHONY: all deps build build-cpp build-asan firmware test demo demo-loop bench study fuzz hil flash data \
        install-onboard run-offboard clean help onboard-arm bench-arm results soak wind-table

all: build

help:
	@sed -n '1,/^SHELL/p' Makefile | grep '^#' | sed 's/^# \{0,1\}//'

deps:
	@scripts/deps.sh

build: deps
	@scripts/build.sh

firmware: deps
	$(call component,firmware/build.sh,)

test: build
	@scripts/test.sh

demo: build
	@scripts/demo.sh

# Ten consecutive `make demo` flights and one summary (hil/tools/demo_loop.py; RUNS=N for another count).
demo-loop: build
	@.venv/bin/python hil/tools/demo_loop.py --runs $(or $(RUNS),10); status=$$?; \
	  python3 scripts/results_write.py demo-loop || true; exit $$status

# Hold error against gust strength, cascade and thesis PID (hil/tools/wind_table.py; docs/hil.md).
wind-table: build
	@.venv/bin/python hil/tools/wind_table.py

bench: build
	@scripts/bench.sh

# TUM sequences from the benchmark's site, verified against pinned sizes and sha256, cut into the
# excerpts the benchmarks read (stdlib Python, no deps). GET_TUM_ARGS: e.g. --trust-on-first-use.
data:
	@scripts/get-tum.sh $(GET_TUM_ARGS) $(SEQ)

# The one page of dated figures, from the result files the benchmark runs wrote (stdlib only).
results:
	@python3 scripts/results.py

study: build
	$(call component,offboard/study/study.sh,)

fuzz: build
	@FUZZ_SECONDS=$(FUZZ_SECONDS) scripts/fuzz.sh

hil: build
	$(call component,hil/run.sh,)

soak: build
	$(call component,hil/soak/run.sh,)

flash: firmware
	$(call component,firmware/flash.sh,$(PORT))

install-onboard: build
	$(call component,onboard/install.sh,)

onboard-arm: deps
	@scripts/onboard-arm.sh $(ARCH) --package $(if $(TEST),--test,)

bench-arm: build
	@scripts/onboard-arm.sh arm64 && scripts/onboard-arm.sh armhf && onboard/bench-arm.sh

run-offboard: build
	$(call component,offboard/quadcontrol/run-offboard.sh,)

clean:
	rm -rf build build-asan build-fuzz build-arm64 build-armhf firmware/.pio test-artifacts
