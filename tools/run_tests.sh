#!/usr/bin/env bash
# Runs every test of the package: pytest on the folders of pytest.ini (test/unit, test/nodes,
# test/integration) on both cores, then each launched test in test/rostest/*.test under
# rostest. Fails when any test fails or when nothing ran. Says how long the tests took.
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

started=$SECONDS
status=0
if [[ $part != rostest ]]; then
  echo "=== unit and integration tests (pytest, both cores) ==="
  # -n 2: a worker per core (xdist); --dist loadgroup: tests marked with one xdist_group
  # (those that share something only one may use at a time) run on one worker, in turn.
  # --durations: the ten slowest, where the next speed-up is to be had.
  python -m pytest -q -p no:cacheprovider -n 2 --dist loadgroup --durations=10
  rc=$?
  if [[ $rc -eq 5 ]]; then echo "pytest collected no tests: failing"; status=1
  elif [[ $rc -ne 0 ]]; then status=1; fi
fi
pytest_took=$((SECONDS - started))
if [[ $part == unit ]]; then echo "wall time: tests ${pytest_took} s"; exit $status; fi

echo "=== integration tests (rostest) ==="
passed=0; failed=0; failed_names=()
rostest_out=$(mktemp -d)
shopt -s nullglob
tests=(test/rostest/*.test)
rm -f "$ROS_LOG_DIR/fuzz_counts.txt"
if ((${#tests[@]} == 0)); then echo "no rostest files: failing"; status=1; fi
for t in "${tests[@]}"; do
  echo "--- rostest $t"
  # Not --text: with it rostest exits 0 even when a test fails. Without it the nodes' output
  # goes to $ROS_LOG_DIR and rostest prints each failure with its traceback.
  out="$rostest_out/$(basename "$t").txt"
  rostest "$t" 2>&1 | tee "$out"
  if [[ ${PIPESTATUS[0]} -eq 0 ]]; then passed=$((passed+1))
  else failed=$((failed+1)); failed_names+=("$t"); status=1; fi
done
# The fuzz test's counts (sent, error replies, closed, survived), which rostest keeps in a file.
if [[ -f "$ROS_LOG_DIR/fuzz_counts.txt" ]]; then cat "$ROS_LOG_DIR/fuzz_counts.txt"; fi
# CI keeps only the end of this output: say there which tests failed, and how.
for t in "${failed_names[@]}"; do
  echo "--- FAILED rostest $t:"
  grep -E "FAIL|Error|assert|Traceback|\[failed\]" "$rostest_out/$(basename "$t").txt" | tail -15
done
rm -rf "$rostest_out"
echo "wall time: tests $((SECONDS - started)) s (pytest ${pytest_took} s, rostest $((SECONDS - started - pytest_took)) s)"
echo "rostest: $passed passed, $failed failed${failed_names[*]:+: ${failed_names[*]}}"
exit $status
