#!/usr/bin/env bash
# Runs every test of the package: pytest on the folders of pytest.ini (test/unit, test/nodes,
# test/integration) on both cores and, beside it, each launched test in test/rostest/*.test
# under rostest, in two lanes (the longest first). Fails when any test fails or when nothing
# ran. Says how long the tests took.
# Usage: run_tests.sh [all|unit|rostest]   (make test, make unit, make rostest)
set -uo pipefail
part=${1:-all}
case "$part" in
  all|unit|rostest) ;;
  *) echo "run_tests.sh: unknown part '$part' (one of: all, unit, rostest)" >&2; exit 2 ;;
esac
if (($# > 1)); then echo "run_tests.sh: one part only, got: $*" >&2; exit 2; fi
repo=$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)
cd "$repo"
# shellcheck source=/dev/null
set +u; source env.sh; set -u
export ROS_LOG_DIR="$repo/.ws/log"
# One OpenBLAS thread per process: its extra threads spin between products and, beside the
# other lanes, take the cores the work needs (test/conftest.py says the same for pytest).
export OPENBLAS_NUM_THREADS=1
work=$(mktemp -d)
trap 'rm -rf "$work"' EXIT

# The launched tests, in ROSTEST_LANES lanes (2 by default) that take the next file of one
# queue, the longest first (a file not in LONGEST_ROSTESTS goes first of all: it may be
# long). Each rostest's master takes a free port of its own, and the stacks the tests start
# take free ports too (hrc_stack.start_stack, pick_ports), so two run side by side. Each
# one's output in $work, then a line "passed|failed <file> <seconds>" in
# $work/rostest.results.
LONGEST_ROSTESTS=(loop_faults experiment_streams clean_end hrc experiment experiment_sequence
                  fuzz sequence learning fabric viz window world_sim_time world)
rostest_queue() {
  shopt -s nullglob
  local t name known=() unknown=()
  for name in "${LONGEST_ROSTESTS[@]}"; do
    [[ -f test/rostest/$name.test ]] && known+=("test/rostest/$name.test")
  done
  for t in test/rostest/*.test; do
    name=$(basename "$t" .test)
    [[ " ${LONGEST_ROSTESTS[*]} " == *" $name "* ]] || unknown+=("$t")
  done
  printf '%s\n' "${unknown[@]}" "${known[@]}" | grep -v '^$'
}
next_rostest() {   # the queue's next file (removed from it), or nothing
  ( flock 9; head -n 1 "$work/rostest.queue"; sed -i 1d "$work/rostest.queue" ) \
    9> "$work/rostest.lock"
}
rostest_lane() {
  local t out began
  # A log folder of the lane's own: roslaunch replaces the folder's "latest" link at each
  # start, and two starting at once in one folder print "cannot create a symlink to latest
  # log directory" (seen: a launch refusal test of pytest, which reads its one line).
  export ROS_LOG_DIR="$ROS_LOG_DIR/rostest_lane$1"
  while t=$(next_rostest) && [[ -n $t ]]; do
    out="$work/$(basename "$t").txt"
    began=$SECONDS
    # Not --text: with it rostest exits 0 even when a test fails. Without it the nodes'
    # output goes to $ROS_LOG_DIR and rostest prints each failure with its traceback.
    if { echo "--- rostest $t"; rostest "$t"; } > "$out" 2>&1; then
      echo "passed $t $((SECONDS - began))" >> "$work/rostest.results"
    else
      echo "failed $t $((SECONDS - began))" >> "$work/rostest.results"
    fi
  done
}
rostests() {
  local lanes=() n
  rm -f "$ROS_LOG_DIR"/rostest_lane*/fuzz_counts.txt
  rostest_queue > "$work/rostest.queue"
  for ((n = 0; n < ${ROSTEST_LANES:-2}; n++)); do rostest_lane "$n" & lanes+=($!); done
  wait "${lanes[@]}"
}

started=$SECONDS
status=0
if [[ $part != unit ]]; then
  # Beside pytest: the stacks and the masters of the launched tests spend much of their time
  # waiting (a stack's start, a step's simulated seconds), which pytest's workers fill.
  rostests & lane=$!
fi
if [[ $part != rostest ]]; then
  echo "=== unit and integration tests (pytest, both cores; the launched tests run beside it) ==="
  # -n 2: a worker per core (xdist); --dist loadgroup: tests marked with one xdist_group
  # (those that share something only one may use at a time) run on one worker, in turn.
  # --durations: the ten slowest, where the next speed-up is to be had.
  # --no-loadscope-reorder: in the order of collection, which test/conftest.py sets (the
  # longest first).
  python -m pytest -q -p no:cacheprovider -n 2 --dist loadgroup --no-loadscope-reorder \
    --durations=10
  rc=$?
  if [[ $rc -eq 5 ]]; then echo "pytest collected no tests: failing"; status=1
  elif [[ $rc -ne 0 ]]; then status=1; fi
fi
pytest_took=$((SECONDS - started))
if [[ $part == unit ]]; then echo "wall time: tests ${pytest_took} s"; exit $status; fi

wait "$lane"
echo "=== integration tests (rostest) ==="
passed=0; failed=0; failed_names=()
while read -r outcome t seconds; do
  cat "$work/$(basename "$t").txt"
  echo "($t: ${seconds} s)"
  if [[ $outcome == passed ]]; then passed=$((passed+1))
  else failed=$((failed+1)); failed_names+=("$t"); status=1; fi
done < <(cat "$work/rostest.results" 2>/dev/null)
if ((passed + failed == 0)); then echo "no rostest files: failing"; status=1; fi
# The fuzz test's counts (sent, error replies, closed, survived), which rostest keeps in a file.
for counts in "$ROS_LOG_DIR"/rostest_lane*/fuzz_counts.txt; do
  if [[ -f $counts ]]; then cat "$counts"; fi
done
# CI keeps only the end of this output: say there which tests failed, and how.
for t in "${failed_names[@]}"; do
  echo "--- FAILED rostest $t:"
  grep -E "FAIL|Error|assert|Traceback|\[failed\]" "$work/$(basename "$t").txt" | tail -15
done
if [[ $part == all ]]; then
  echo "wall time: tests $((SECONDS - started)) s (pytest ${pytest_took} s, the launched tests beside it)"
else
  echo "wall time: tests $((SECONDS - started)) s"
fi
echo "rostest: $passed passed, $failed failed${failed_names[*]:+: ${failed_names[*]}}"
exit $status
