#!/usr/bin/env bash
# Submit a campaign and, chained after it, its calibration; print the job ids.
#
#   jobs/submit.sh CONFIG.toml STORE.h5 OUTDIR [-- SBATCH_OPTIONS_FOR_THE_CAMPAIGN...]
#   e.g. jobs/submit.sh campaigns/demo.toml demo.h5 demo-analysis -- --ntasks=8 --time=2:00:00
#
# The campaign runs jobs/campaign.sbatch; the analysis (jobs/analysis.sbatch)
# waits with --dependency=afterok:<campaign> and so starts only when the store
# is complete. The campaign job finishes the store by itself: when its time
# limit nears, or its campaign step is lost with a node, it requeues itself
# (same job id; the analysis keeps waiting) and resumes, at most
# CORTEX_MAX_REQUEUES times (default 10, read when the job runs). If it ends
# short of complete (failed tasks, no requeue left, cancelled) it exits
# non-zero and its analysis is cancelled (--kill-on-invalid-dep=yes). To
# resume, run the same command again, or jobs/resume.sh with the same
# arguments (it first checks the store and says how far it got): the new
# campaign job picks up the tasks not yet done and a new analysis is chained
# to it.
#
# Prints `campaign JOBID` and `analysis JOBID` on two lines (stdout). Works from
# any directory: paths are relative to where it is called, and the jobs run
# there (their logs, cortex-campaign-JOBID.out and cortex-analysis-JOBID.out,
# land there too). CORTEX_MAX_REQUEUES, CORTEX_VENV and CORTEX_CMD pass through to the jobs.
set -euo pipefail

if (($# < 3)); then
    sed -n '2,/^set /p' "$0" | sed '$d; s/^# \{0,1\}//' >&2
    exit 2
fi
config=$1 store=$2 out=$3
shift 3
[[ ${1:-} == -- ]] && shift
export CORTEX_ROOT=${CORTEX_ROOT:-$(cd "$(dirname "$0")/.." && pwd)}
jobs=$CORTEX_ROOT/jobs

[[ -f $config ]] || { echo "submit.sh: error: no campaign config $config" >&2; exit 2; }

campaign=$(CORTEX_OUT=$out sbatch --parsable "$@" "$jobs/campaign.sbatch" "$config" "$store")
campaign=${campaign%%;*}
analysis=$(sbatch --parsable --dependency="afterok:$campaign" --kill-on-invalid-dep=yes \
    "$jobs/analysis.sbatch" "$store" "$out")
analysis=${analysis%%;*}
echo "campaign $campaign"
echo "analysis $analysis"
