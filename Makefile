# Entry points for people: `make demo` and `make test` do all the set-up
# (Debian packages when run as root, configure, build) themselves.
BUILD      ?= build
SAN_BUILD  ?= build-sanitize
WERROR     ?= $(if $(CI),ON,OFF)
JOBS       ?= 2
CMAKE_GEN  := -G Ninja

.PHONY: all deps build test test-sanitize demo bench install clean

all: build

deps:
	@bash scripts/install-deps.sh

build: deps
	cmake -S . -B $(BUILD) $(CMAKE_GEN) -DCMAKE_BUILD_TYPE=Release -DPSYS_WERROR=$(WERROR)
	cmake --build $(BUILD) -j $(JOBS)

test: build
	ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS)

# The same suite under AddressSanitizer + UndefinedBehaviorSanitizer.
test-sanitize: deps
	cmake -S . -B $(SAN_BUILD) $(CMAKE_GEN) -DCMAKE_BUILD_TYPE=Debug -DPSYS_SANITIZE=ON -DPSYS_WERROR=$(WERROR)
	cmake --build $(SAN_BUILD) -j $(JOBS)
	ctest --test-dir $(SAN_BUILD) --output-on-failure -j $(JOBS)

demo: build
	bash scripts/demo.sh $(BUILD)/psys

bench: build
	$(BUILD)/psys bench

install: build
	cmake --install $(BUILD)

clean:
	rm -rf $(BUILD) $(SAN_BUILD) out
