#!/usr/bin/env bash
# Resume a campaign that stopped short of complete (out of requeues,
# cancelled, failed), and chain its calibration again; print the job ids.
#
#   jobs/resume.sh CONFIG.toml STORE.h5 OUTDIR [-- SBATCH_OPTIONS_FOR_THE_CAMPAIGN...]
#
# The same arguments as jobs/submit.sh, which it calls after checking that
# STORE.h5 exists and printing how far it got (`cortex campaign status`, on
# stderr). The new campaign job skips the tasks already done and redoes those
# that were interrupted; the analysis waits for it with afterok. A campaign
# job that stopped without requeueing itself prints this command at the end
# of its log (cortex-campaign-JOBID.out).
#
# Prints `campaign JOBID` and `analysis JOBID` on two lines (stdout).
set -euo pipefail

if (($# < 3)); then
    sed -n '2,/^set /p' "$0" | sed '$d; s/^# \{0,1\}//' >&2
    exit 2
fi
export CORTEX_ROOT=${CORTEX_ROOT:-$(cd "$(dirname "$0")/.." && pwd)}
store=$2
[[ -f $store ]] || { echo "resume.sh: error: no store $store to resume (start the campaign with jobs/submit.sh)" >&2; exit 2; }
cortex=${CORTEX_CMD:-${CORTEX_VENV:-$CORTEX_ROOT/.venv}/bin/cortex}
"$cortex" campaign status "$store" >&2 || { echo "resume.sh: error: cannot read the store $store" >&2; exit 2; }
exec "$CORTEX_ROOT/jobs/submit.sh" "$@"
