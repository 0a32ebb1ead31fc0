# Sourced by .ci/setup and .ci/packages (after they cd to the checkout's root).
# Quiet on success, loud on failure: whatever ends a script with a non-zero
# status (set -e, a pipeline killed by SIGPIPE, an explicit exit) prints the
# step it was in, the command that failed and the end of the log that apt's
# and pip's output went to.  The setup once died with exit 141 and not a word.
set -Eeuo pipefail
log=${GLVOX_SETUP_LOG:-.venv-setup.log}
step="starting"
failed_cmd=""
reported=""   # set where a child script has already reported its own failure

# The ERR trap only records the command: with -E it also runs inside command
# substitutions and functions, where printing would say it twice or in the
# wrong place.  The EXIT trap reports, once, in the script itself.
trap 'failed_cmd=$BASH_COMMAND' ERR
trap 'report_failure $?' EXIT

report_failure() {
  local rc=$1
  trap - EXIT
  if [ "$rc" -ne 0 ] && [ -z "$reported" ]; then
    echo "setup: FAILED (exit $rc) at step: $step${failed_cmd:+ (command: $failed_cmd)}" >&2
    if [ -s "$log" ]; then
      echo "setup: the end of $log:" >&2
      tail -n 30 "$log" >&2
    else
      echo "setup: ($log is empty)" >&2
    fi
  fi
  exit "$rc"
}
