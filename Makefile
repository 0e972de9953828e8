# The README's commands. Everything a command needs is installed by scripts/install-deps.sh.
BUILD_DIR ?= build
JOBS ?= $(shell nproc)
DEMO_DIR ?= out/demo
DEMO_PORT ?= 8080

.PHONY: deps configure build demo test bench fuzz tsan tsan-threads clean

deps:
	./scripts/install-deps.sh

configure: deps
	cmake -S . -B $(BUILD_DIR) -DCMAKE_BUILD_TYPE=Release

build: configure
	cmake --build $(BUILD_DIR) -j $(JOBS)

# The main job on a built-in synthetic capture: 4 Kinect-like cameras around a walking, waving person.
demo: build
	rm -rf $(DEMO_DIR)
	$(BUILD_DIR)/zipfusion synth --out $(DEMO_DIR)/capture --frames 30 --cameras 4
	$(BUILD_DIR)/zipfusion info $(DEMO_DIR)/capture
	$(BUILD_DIR)/zipfusion reconstruct $(DEMO_DIR)/capture --out $(DEMO_DIR)/meshes
	$(BUILD_DIR)/zipfusion eval $(DEMO_DIR)/capture $(DEMO_DIR)/meshes
	@echo
	@echo "demo results:"
	@echo "  capture (rig.json, cam*/depth, cam*/color): $(abspath $(DEMO_DIR)/capture)"
	@echo "  ground truth (true poses, true meshes):     $(abspath $(DEMO_DIR)/capture/ground_truth)"
	@echo "  one zippered, coloured mesh per frame:      $(abspath $(DEMO_DIR)/meshes)/000000.ply ..."
	@echo "  timings per stage:                          $(abspath $(DEMO_DIR)/meshes)/stats.json"
	@echo
	@echo "now streaming the capture live: open the URL below in a browser (Ctrl-C stops)"
	$(BUILD_DIR)/zipfusion serve $(DEMO_DIR)/capture --loop --port $(DEMO_PORT)

test: build
	cd $(BUILD_DIR) && ctest --output-on-failure -j $(JOBS)

# Every benchmark, then docs/benchmarks.md from the results (about 10 minutes on 2 cores).
bench: build
	BUILD_DIR=$(BUILD_DIR) scripts/bench.sh
	$(BUILD_DIR)/zf_registration_bench --benchmark_repetitions=5 --benchmark_report_aggregates_only=true

# Each fuzz target (fuzz/) under libFuzzer with ASan and UBSan, FUZZ_SECONDS each; a finding fails
# and is kept in $(FUZZ_DIR)/findings/. Not part of `make test`, which replays the corpus instead.
FUZZ_DIR ?= build-fuzz
FUZZ_SECONDS ?= 60
fuzz:
	./scripts/install-deps.sh --fuzz
	cmake -S . -B $(FUZZ_DIR) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_CXX_COMPILER=clang++ -DZF_FUZZ=ON -DZF_BUILD_TESTS=OFF -DZF_BUILD_BENCH=OFF
	cmake --build $(FUZZ_DIR) -j $(JOBS) --target zf_fuzz_all
	scripts/fuzz.sh $(FUZZ_DIR) $(FUZZ_SECONDS)

# Every test built with ThreadSanitizer into $(TSAN_DIR): a data race or lock-order inversion fails
# its test (scripts/tsan.sh). Not part of `make test`: the build takes about 15 minutes on 2 cores
# and the threaded tests run 5–15 times slower.
TSAN_DIR ?= build-tsan
tsan: deps
	cmake -S . -B $(TSAN_DIR) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DZF_TSAN=ON -DZF_BUILD_BENCH=OFF
	cmake --build $(TSAN_DIR) -j $(JOBS)
	scripts/tsan.sh $(TSAN_DIR) -j $(JOBS)

# Only the tests that run zipfusion's own threads (CTest label "threads", CMakeLists.txt), built
# with ThreadSanitizer: about 8 minutes to build and 5 to run on 2 cores. CI runs it after `make test`.
tsan-threads: deps
	cmake -S . -B $(TSAN_DIR) -DCMAKE_BUILD_TYPE=RelWithDebInfo -DZF_TSAN=ON -DZF_BUILD_BENCH=OFF
	cmake --build $(TSAN_DIR) -j $(JOBS) --target zf_threaded_tests
	scripts/tsan.sh $(TSAN_DIR) -j $(JOBS) -L threads

clean:
	rm -rf $(BUILD_DIR) $(FUZZ_DIR) $(TSAN_DIR) out
