# Thin wrapper over the CMake presets. The two commands of the README:
#   make demo   builds only the programs it runs (not the tests) and runs the main job: the
#               paper's experiment in a device-sized memory cgroup
#   make test   installs what is missing, then runs every test: host (ASan + UBSan) and
#               aarch64 (cross-built, under qemu-aarch64), the Debian packages and the installed library
JOBS ?= $(shell nproc)
CTEST_FLAGS ?= -j $(JOBS)

.PHONY: all deps deps-host test test-host test-aarch64 test-package package release demo bench fuzz fuzz-ci format tidy clean

all: release

deps:
	bash scripts/install-deps.sh

deps-host:
	bash scripts/install-deps.sh --host

test: deps
	$(MAKE) test-host
	$(MAKE) test-aarch64
	$(MAKE) test-package
	$(MAKE) fuzz-ci

test-host:
	cmake --preset host-debug
	cmake --build --preset host-debug -j $(JOBS)
	ctest --preset host-debug $(CTEST_FLAGS)

test-aarch64:
	cmake --preset aarch64-release
	cmake --build --preset aarch64-release -j $(JOBS)
	ctest --preset aarch64-release $(CTEST_FLAGS)
	# NEON forced off: the scalar kernels on aarch64 (the SIMD tests only).
	cmake --preset aarch64-scalar
	cmake --build --preset aarch64-scalar -j $(JOBS) --target zm_simd_test
	qemu-aarch64 -L $${ZM_ARM64_SYSROOT:-/opt/zonemap/sysroot-arm64} build/aarch64-scalar/tests/simd/zm_simd_test
	# The cross-built zonemapd on a small simulated scenario, under qemu-aarch64.
	bash scripts/qemu-run.sh

# The Debian packages (amd64 from the `package` preset, arm64 from aarch64-release), checked,
# installed into scratch roots with dpkg --root, run, and consumed by a separate project built
# against the installed package on both architectures (scripts/package-test.sh, docs/api.md).
# Needs the aarch64-release build of test-aarch64.
test-package:
	JOBS=$(JOBS) bash scripts/package-test.sh

# Just the packages: build/package/packages/*.deb (amd64) and build/aarch64-release/packages/*.deb.
package: deps
	cmake --preset package
	cmake --build --preset package -j $(JOBS)
	cd build/package && cpack -G DEB
	cmake --preset aarch64-release
	cmake --build --preset aarch64-release -j $(JOBS)
	cd build/aarch64-release && cpack -G DEB

release: deps-host
	cmake --preset host-release
	cmake --build --preset host-release -j $(JOBS)

# The demo builds only what it runs: the programs, not the test suites and benchmarks (the
# README states how long a fresh machine takes). ZM_DEMO_* knobs in scripts/demo.sh.
APPS = zonemap zonemap-cotenant zonemapd

demo: deps-host
	cmake --preset host-release
	cmake --build --preset host-release -j $(JOBS) --target $(APPS)
	bash scripts/demo.sh

sweep: deps-host  # where Basic breaks (issue 17 §7): a few minutes at 1/8, not part of `make test`
	cmake --preset host-release
	cmake --build --preset host-release -j $(JOBS) --target zonemap zonemap-cotenant
	/usr/bin/python3 scripts/sweep.py measure

bench: release
	bash scripts/bench.sh

fuzz:  # libFuzzer targets (clang-14), FUZZ_SECONDS per target (docs/reliability.md)
	bash scripts/fuzz.sh $(FUZZ_SECONDS)

fuzz-ci:  # bounded run for `make test`: 15 s a target, two at a time, after the clang build
	bash scripts/fuzz.sh 15

format:
	git ls-files '*.h' '*.cc' | xargs clang-format -i

# clang-tidy reads each file's own compile command, which a unity build does not have: its own
# file-by-file configuration (nothing is built there).
tidy:
	cmake --preset host-release -B build/tidy -DCMAKE_UNITY_BUILD=OFF
	git ls-files 'arena/*.cc' 'lib/*.cc' 'app/*.cc' | xargs clang-tidy -p build/tidy --quiet

clean:
	rm -rf build
