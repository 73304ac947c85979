#!/usr/bin/env bash
# CI's sanitizer and fuzz stage (issue 26 items 3 and 4), run after the Release tests by the
# README's test command. Builds ./build-san with clang (libFuzzer exists only in clang) with
# AddressSanitizer and UndefinedBehaviorSanitizer (-DECO_SANITIZE=address,undefined) and the
# fuzz targets (-DECO_FUZZ=ON), runs the unit and command-line tests under the sanitizers,
# then each fuzz target for a bounded time on its seed corpus. Any sanitizer report, test
# failure or fuzz finding fails the script. docs/robustness.md says how to run it longer.
#   environment: ECO_FUZZ_SECONDS (per target, default 15), ECO_FUZZ_SEED (libFuzzer's -seed,
#   default 1), ECO_SAN_BUILD (default build-san)
set -euo pipefail
cd "$(dirname "$0")/.."
root=$(pwd)
build=${ECO_SAN_BUILD:-build-san}
fuzz_seconds=${ECO_FUZZ_SECONDS:-15}
fuzz_seed=${ECO_FUZZ_SEED:-1}
start=$(date +%s)
stamp() { echo "sanitize: $1 ($(( $(date +%s) - start )) s)"; }

# clang with its sanitizer and libFuzzer runtimes, and LLVM's OpenMP runtime (clang's
# -fopenmp links libomp, not gcc's libgomp).
source tools/apt_install.sh
install_missing sanitize clang libclang-rt-14-dev libomp-dev

work=$(mktemp -d "${TMPDIR:-/tmp}/eco-sanitize-XXXXXX")
# LLVM's OpenMP runtime registers each process in /dev/shm/__KMP_REGISTERED_LIB_<pid>_<uid>
# and removes the file when the process exits normally; the processes that the kill tests and
# the fuzz findings end leave theirs. Those of dead processes are removed at the end.
clean_kmp() {
  local f pid
  for f in /dev/shm/__KMP_REGISTERED_LIB_*; do
    [ -e "$f" ] || continue
    pid=${f#/dev/shm/__KMP_REGISTERED_LIB_}
    pid=${pid%%_*}
    kill -0 "$pid" 2> /dev/null || rm -f "$f"
  done
}
trap 'rm -rf "$work"; clean_kmp' EXIT
launcher=()
if command -v ccache > /dev/null; then
  launcher=(-DCMAKE_C_COMPILER_LAUNCHER=ccache -DCMAKE_CXX_COMPILER_LAUNCHER=ccache)
fi
# -O1: the sanitizers' usual level (fast enough, exact stacks); assertions stay on. Line tables
# only (-gline-tables-only): the reports' stacks keep file, line and function, and the build
# spends far less time writing debug information (the whole CI must stay under 30 minutes).
cmake -S . -B "$build" -DCMAKE_C_COMPILER=clang -DCMAKE_CXX_COMPILER=clang++ \
  -DCMAKE_BUILD_TYPE=RelWithDebInfo -DCMAKE_C_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" -DCMAKE_CXX_FLAGS_RELWITHDEBINFO="-O1 -gline-tables-only" \
  -DECO_SANITIZE=address,undefined -DECO_FUZZ=ON -DECO_BUILD_BENCH=OFF "${launcher[@]}" > "$work/configure.log" 2>&1 \
  || { cat "$work/configure.log"; exit 1; }
stamp "configured $build"
# Only what the tests and the fuzz runs need (no benchmarks).
cmake --build "$build" -j"$(nproc)" --target eco eco_tests eco_geo_tests eco_synth_tests eco_sim_tests eco_analysis_tests \
  eco_pipeline_tests eco_validate_tests eco_cli_tests eco_fuzz
stamp "built"

# Leaks: every report fails except the third-party ones listed (with why) in lsan.supp.
# UBSan: halt on the first report (the build also has -fno-sanitize-recover=undefined).
# intercept_tls_get_addr=0: OpenImageIO and GDAL are loaded with dlopen (the plugins, core/plugin.h),
# so their thread-local storage is dynamic; LLVM 14's LeakSanitizer records a bogus dynamic-TLS
# range for it under glibc 2.36 (0x2890-0x800003992 at the exit of a test that wrote a PNG) and its
# tracer crashes there ("Tracer caught signal 11"). Without the interception the dynamic TLS
# blocks of those libraries are not scanned; the static TLS and every stack and heap still are.
export ASAN_OPTIONS="detect_leaks=1:strict_string_checks=1:detect_stack_use_after_return=1:check_initialization_order=1:intercept_tls_get_addr=0"
export LSAN_OPTIONS="suppressions=$root/tools/sanitize/lsan.supp:print_suppressions=0"
export UBSAN_OPTIONS="print_stacktrace=1:halt_on_error=1:suppressions=$root/tools/sanitize/ubsan.supp"

# The whole suite except `eco validate --quick` end to end (label validation): about 25 s in
# Release, several minutes under the sanitizers, and it runs no reader the other tests
# do not; the Release stage runs it.
# The test that feeds OpenImageIO a damaged PNG runs on its own with full stack unwinding at
# every allocation: the leak inside OpenImageIO (lsan.supp) is allocated from libstdc++, which
# keeps no frame pointers, so the fast unwinder stops there and the suppression, which names
# OpenImageIO's function, could not match. Full unwinding everywhere doubles the run time.
png_error_tests='^terrain: a corrupt image is named$'
# Also left out: the slowest compute-bound tests (25-125 s each under the sanitizers on 2
# cores, a quarter of the sanitized test time), which read no input the others do not: thread
# identity of synthesis and fidelity, refinement, and the end-to-end runs of eco run and eco
# fidelity (fuzz/make_seeds.sh below runs a small eco run under the sanitizers). The Release
# stage runs them all.
# Also eco synth --method xu2015 from CSV exemplars (three syntheses; its sampler's unit tests and
# its readers' refusals run sanitized in eco_synth_tests and the corpus of bad inputs).
# Also the succession / Deussen-comparison checks under the literal growth rule, and the other
# broken-model runs of the suite (the early peak under germination in every cell, the sun
# gradient of a biome blind to the sun: two 150-year forest runs each; their measures, the
# suite's code and eco validate --biome's reading run sanitized in the other tests).
# Also the ensemble's runs: its members and database, its kill test and its comparison of
# child processes and MPI ranks with one process (one to three ensemble runs of three members
# each; the specification reader runs sanitized in the others), and those of eco sensitivity (twelve
# simulations for Morris, sixteen for Sobol) and eco calibrate (about twelve; six for its global options; sixteen, eight of them under
# two MPI ranks, for its parallel starts; twelve for crs's rounds with 1 and 2 members at once and 2 MPI ranks; their specification, search and report code run
# sanitized in the other tests). Also the HDF5 schema walk (a whole small eco run, about 3 s in
# Release; h5io's own tests run sanitized), the gap-dynamics broken-model run (two 150-year
# runs of a 45 m plot), the thread-identity tests of provenance (every command and eco run on 1
# and 2 threads: 70 and 33 s sanitized), of the database (24 s) and of the structured sampler
# (15 s), which run the code of other sanitized tests twice more, the succession after a fire (two 90-year runs; 32 s sanitized; the
# fire and storm code runs sanitized in the other disturbance tests) and the install test (it installs this build and compiles a program
# against it without the sanitizer flags).
slow_tests='^(hdf5 schema: every file eco run writes follows docs/hdf5.md.*|Succession and Deussen-comparison checks fail under the literal growth rule|eco synth --method xu2015: a scene from an exemplar CSV.*|eco sensitivity: Morris screening.*|eco sensitivity: Sobol indices through the ensemble.*|eco calibrate: recovers a known.*|eco calibrate: the global search is recorded.*|eco calibrate: parallel starts over two MPI ranks.*|eco calibrate: crs rounds give the same history.*|eco calibrate: .calibrate.scene. fits on eco validate.s forest scene.*|eco ensemble: every member simulated.*|eco ensemble: killed at a checkpoint write.*|eco ensemble: members in child processes.*|synthesis is identical with 1 and 2 threads|the structured sampler.s parallel paths give one scene.*|refinement lowers the pair-correlation distance.*|eco run: the whole pipeline on a small scene.*|eco run: a demo-like configuration copied alone.*|fidelity: CSR scores near 1.*|The fidelity scenario runs on a tiny scene.*|eco fidelity end to end on a tiny plot.*|Succession.s early peak fails when.*|The sun gradient fails for a biome.*|Gap dynamics fail when undergrowth is limited.*|disturbance validation: after a stand-clearing fire.*|cmake --install: a program of one.s own.*|provenance: with --no-provenance every command writes the same bytes on 1 and 2 threads|provenance: with --no-provenance eco run writes the same bytes on 1 and 2 threads|the database is bit-identical with 1 and 2 threads|the structured sampler is identical for 1 and 2 threads)$'
# The test that feeds HDF5 files with a damaged byte: HDF5 1.10.8 leaks small blocks on the
# error paths of damaged files, so it runs with the HDF5 fuzz targets' suppressions.
hdf5_damage_tests='^h5io: a damaged byte anywhere in a file is an error, never a changed value$'
# Labels python and r: the readers' tests in Python and R run eco's commands that the other
# tests run sanitized; the Release stage runs them. Label browser: the HTML reports in headless
# Chromium (the pages' writers run sanitized in the html unit tests and eco run's tests).
# The browser tests' executable is not built here (the target list above), so CTest holds a
# placeholder for it (eco_browser_tests_NOT_BUILT-...) that carries no label: left out by name.
not_built='^eco_browser_tests_NOT_BUILT'
ctest --test-dir "$build" --output-on-failure -j"$(nproc)" -LE '^(validation|python|r|browser|blender)$' -E "$png_error_tests|$hdf5_damage_tests|$slow_tests|$not_built" --timeout 900
ASAN_OPTIONS="$ASAN_OPTIONS:fast_unwind_on_malloc=0" ctest --test-dir "$build" --output-on-failure --no-tests=error -R "$png_error_tests"
LSAN_OPTIONS="suppressions=$root/tools/sanitize/lsan-hdf5-fuzz.supp:print_suppressions=0" \
  ctest --test-dir "$build" --output-on-failure --no-tests=error -R "$hdf5_damage_tests"
stamp "tests passed under ASan and UBSan"

# Seeds: the committed text seeds and files made by our own writers (fuzz/make_seeds.sh).
seeds="$build/fuzz-seeds"
rm -rf "$seeds"
fuzz/make_seeds.sh "$build/apps/eco" "$seeds"
stamp "seed corpus made"

# Each target for a bounded time from the repository root (the run-config seeds name
# configs/ from there). A finding is saved as $build/fuzz-findings/<target>-crash-..., and
# libFuzzer exits non-zero. -rss_limit_mb=2048: a process above 2 GB, or one allocation
# above it, is a finding; the targets give our memory checks half of it (fuzz_common.h).
# A report is HDF5's own when the first frame of its stack below the sanitizer's and
# libFuzzer's own frames (interceptors such as malloc and memcpy compiled into the target,
# the timeout and out-of-memory handlers, libc's signal return) lies in libhdf5: a crash,
# a timeout or an allocation inside the library on a damaged file, whatever frames of ours
# lie further down.
inside_hdf5() {
  awk '/^==[0-9]+== ?ERROR: |^SUMMARY: / { on = 1 }
       on && /^ *#[0-9]+ 0x/ {
         if ($0 ~ /libhdf5/) { found = 1; exit }
         if ($0 ~ / in (__sanitizer|__asan|__lsan|__interceptor_|fuzzer::)/ || $0 ~ /\/libc\.so/ ||
             $0 ~ / in (malloc|calloc|realloc|free|memcpy|memmove|memset|strlen|strnlen|memcmp|operator new|operator delete)[ (]/) next
         exit }
       END { exit !found }' "$1"
}
findings="$build/fuzz-findings"
rm -rf "$findings"
mkdir -p "$findings"
# One target's run; its exit status in $build/fuzz-$target.status. Two run at a time (one per
# core of the CI machine), each for the same bounded time.
fuzz_one() {
  local target=$1
  local corpus="$build/fuzz-corpus/$target"  # new inputs found by this run; the seeds stay as they are
  rm -rf "$corpus"
  mkdir -p "$corpus"
  local options=()
  local asan="$ASAN_OPTIONS"
  local lsan="$LSAN_OPTIONS"
  case $target in
    # Full unwinding, for the OpenImageIO suppression to match (as the PNG test above).
    image) asan="$ASAN_OPTIONS:fast_unwind_on_malloc=0" ;;
    # No leak check after each input: HDF5 keeps freed blocks in its own free lists, so the
    # counts of malloc and free never balance and libFuzzer would scan the whole heap after
    # every input (7 s each). Leaks are still checked once when the run ends.
    # HDF5's own leaks on damaged files are suppressed by library (lsan-hdf5-fuzz.supp).
    biome_db | sim_file | canopy_file | scene)
      options=(-detect_leaks=0)
      lsan="suppressions=$root/tools/sanitize/lsan-hdf5-fuzz.supp:print_suppressions=0" ;;
  esac
  # -seed: the same mutations on every run, so that CI is not a lottery over the third-party
  # crashes of HDF5 below; a long run (docs/robustness.md) draws its own seed.
  local status=0
  LSAN_OPTIONS="$lsan" ASAN_OPTIONS="$asan" "$build/fuzz/fuzz_$target" -seed="$fuzz_seed" -max_total_time="$fuzz_seconds" -rss_limit_mb=2048 -timeout=20 \
    -print_final_stats=1 -artifact_prefix="$findings/$target-" "${options[@]}" "$corpus" "$seeds/$target" \
    > "$build/fuzz-$target.log" 2>&1 || status=$?
  echo "$status" > "$build/fuzz-$target.status"
}
targets=(asc image biome_toml run_config csv biome_db sim_file canopy_file scene)
running=0
for target in "${targets[@]}"; do
  if [ "$running" -ge 2 ]; then
    wait -n
    running=$((running - 1))
  fi
  fuzz_one "$target" &
  running=$((running + 1))
done
wait
status=0
for target in "${targets[@]}"; do
  if [ "$(cat "$build/fuzz-$target.status")" = 0 ]; then
    echo "sanitize: fuzz_$target: $(grep -E '^stat::number_of_executed_units' "$build/fuzz-$target.log" | awk '{print $2}') runs," \
      "$(grep -oE 'cov: [0-9]+' "$build/fuzz-$target.log" | tail -1), no finding"
  elif inside_hdf5 "$build/fuzz-$target.log"; then
    # A crash inside the HDF5 library itself that the targets' walk of the file did not
    # foresee (it can depend on the library's state): third party, not a finding of ours
    # (docs/robustness.md). Shown, not failed.
    echo "sanitize: fuzz_$target: stopped inside HDF5 1.10.8 (a crash, timeout or allocation there; third party; input in $findings/):"
    grep -E '^SUMMARY|^    #[0-9]+ ' "$build/fuzz-$target.log" | head -n 12
  else
    echo "sanitize: fuzz_$target FOUND A PROBLEM (input saved in $findings/):"
    tail -n 60 "$build/fuzz-$target.log"
    status=1
  fi
done
stamp "fuzzing done"
exit $status
