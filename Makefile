# Entry points for people: `make demo` and `make test` do all the set-up
# (Debian packages when run as root, configure, build) themselves.
BUILD      ?= build
SAN_BUILD  ?= build-sanitize
WERROR     ?= $(if $(CI),ON,OFF)
JOBS       ?= 2
CMAKE_GEN  := -G Ninja

.PHONY: all deps configure build test test-sanitize test-mpi test-mpi-sanitize fuzz demo images bench install clean

all: build

deps:
	@bash scripts/install-deps.sh

configure: deps
	cmake -S . -B $(BUILD) $(CMAKE_GEN) -DCMAKE_BUILD_TYPE=Release -DPSYS_WERROR=$(WERROR)

build: configure
	cmake --build $(BUILD) -j $(JOBS)

test: build
	ctest --test-dir $(BUILD) --output-on-failure -j $(JOBS)

# The same suite under AddressSanitizer + UndefinedBehaviorSanitizer (the
# libFuzzer smoke runs are in `make test`; the corpus replays run here too).
test-sanitize: deps
	cmake -S . -B $(SAN_BUILD) $(CMAKE_GEN) -DCMAKE_BUILD_TYPE=Debug -DPSYS_SANITIZE=ON -DPSYS_WERROR=$(WERROR) \
	      -DPSYS_FUZZ_TARGETS=OFF
	cmake --build $(SAN_BUILD) -j $(JOBS)
	ctest --test-dir $(SAN_BUILD) --output-on-failure -j $(JOBS)

# The MPI build (docs/mpi.md): the same psys built with -DPSYS_MPI=ON in its
# own directory, and the MPI tests (label mpi): 2 and 4 ranks under mpiexec
# on this machine (oversubscribed), byte for byte against the serial run.
MPI_BUILD ?= build-mpi
test-mpi: deps
	cmake -S . -B $(MPI_BUILD) $(CMAKE_GEN) -DCMAKE_BUILD_TYPE=Release -DPSYS_MPI=ON -DPSYS_WERROR=$(WERROR)
	cmake --build $(MPI_BUILD) -j $(JOBS) --target psys_cli test_mpi
	ctest --test-dir $(MPI_BUILD) --output-on-failure -j $(JOBS) -L mpi

# The MPI tests again with ASan + UBSan (Debug). Leak checking is off here:
# MPICH's transport plugins leak about 1 KB at exit from code without symbols
# (the same with --mpi replicated); psys's own leaks are checked by
# test-sanitize, which runs the whole library without MPI.
MPI_SAN_BUILD ?= build-mpi-sanitize
test-mpi-sanitize: deps
	cmake -S . -B $(MPI_SAN_BUILD) $(CMAKE_GEN) -DCMAKE_BUILD_TYPE=Debug -DPSYS_SANITIZE=ON -DPSYS_MPI=ON \
	      -DPSYS_WERROR=$(WERROR) -DPSYS_FUZZ_TARGETS=OFF
	cmake --build $(MPI_SAN_BUILD) -j $(JOBS) --target psys_cli test_mpi
	ASAN_OPTIONS=detect_leaks=0 UBSAN_OPTIONS=halt_on_error=1:print_stacktrace=1 \
	    ctest --test-dir $(MPI_SAN_BUILD) --output-on-failure -j $(JOBS) -L mpi

# Long fuzzing runs (docs/trust.md): FUZZ_SECONDS per target (scene loader,
# CLI parser); the corpus grows in $(BUILD)/fuzz-corpus/, crashes land in
# $(BUILD)/fuzz-artifacts/. Needs clang with libFuzzer (make deps installs it).
FUZZ_SECONDS ?= 600
FUZZ_FLAGS   ?=
fuzz: build
	bash fuzz/fuzz.sh long scene $(BUILD) $(FUZZ_SECONDS) $(FUZZ_FLAGS)
	bash fuzz/fuzz.sh long cli $(BUILD) $(FUZZ_SECONDS) $(FUZZ_FLAGS)

# The demo needs only the library and the psys program: just that target is
# built (not the tests or the nested libFuzzer build, most of a full build's
# time), in $(BUILD), so a later `make test` builds on it.
demo: configure
	cmake --build $(BUILD) -j $(JOBS) --target psys_cli
	bash scripts/demo.sh $(BUILD)/psys

# The pictures of the examples in README.md (docs/images/*.png).
images: build
	bash scripts/render-examples.sh $(BUILD)/psys

bench: build
	$(BUILD)/psys bench

install: build
	cmake --install $(BUILD)

clean:
	rm -rf $(BUILD) $(SAN_BUILD) $(MPI_BUILD) out
