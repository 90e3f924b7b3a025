# causaldrive: the two commands of the README are `make run` and `make test`.
BUILD_DIR ?= build
JOBS      ?= 2
BUILD_TYPE ?= Release

.PHONY: all setup configure build test run clean

all: build

setup:
	@bash scripts/setup.sh

# Ninja when installed (scripts/setup.sh installs it), for a new build folder; a folder keeps the
# generator it was configured with.
GENERATOR ?= $(if $(shell command -v ninja),-G Ninja,)

configure: setup
	@cmake -S . -B $(BUILD_DIR) $(if $(wildcard $(BUILD_DIR)/CMakeCache.txt),,$(GENERATOR)) \
		-DCMAKE_BUILD_TYPE=$(BUILD_TYPE) >/dev/null

build: configure
	@cmake --build $(BUILD_DIR) -j$(JOBS)

test: build
	@cd $(BUILD_DIR) && ctest --output-on-failure -j2

run: build
	@./$(BUILD_DIR)/causaldrive quickstart

clean:
	rm -rf $(BUILD_DIR)
