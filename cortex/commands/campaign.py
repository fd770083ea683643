"""`cortex campaign run|status|verify|repair`. `run` and `status` take `--json`: the store's
summary (the object `cortex campaign status --json` prints) on stdout; progress and
messages go to stderr. `verify` prints one line per damaged row (exit 1 if any), `repair`
one line per row it rewrote from the journal."""

from __future__ import annotations

import argparse

from cortex.options import Commands


def register(sub: Commands) -> None:
    p = sub.add_parser("campaign", help="run, resume and inspect simulation campaigns (MPI)",
                       description="Run a campaign of shell compressions and Monte-Carlo error trials "
                                   "across MPI ranks into one HDF5 store (mpiexec -n N cortex campaign "
                                   "run ...), resume it, and look at its progress.")
    cs = p.add_subparsers(dest="subcommand", metavar="SUBCOMMAND", required=True)
    r = cs.add_parser("run", help="run or resume a campaign",
                      description="Run or resume the campaign of CONFIG into STORE. Rerunning the same "
                                  "command resumes: done tasks are skipped, interrupted ones redone.")
    r.add_argument("config", metavar="CONFIG.toml", help="campaign file")
    r.add_argument("--store", metavar="STORE.h5", help="the store (default: [campaign] store of the file); "
                   "a folder, or an existing file that is not a campaign store, is refused")
    r.add_argument("--new", action="store_true", help="start over; the old store and journal (ours) are kept as backups")
    r.add_argument("--retry-failed", action="store_true", help="run failed tasks again (a rerun otherwise leaves "
                   "them failed: also those that crashed their process or did not answer)")
    r.add_argument("--quiet", action="store_true", help="no progress output")
    r.add_argument("--json", action="store_true", help="at the end, the store's summary as one JSON object "
                   "(as `cortex campaign status --json`)")
    r.add_argument("--write-path", choices=("auto", "mpio", "rank0"), default="auto",
                   help="how rows reach the store: mpio (every rank writes its own rows by parallel "
                        "HDF5; needs h5py built with MPI), rank0 (rank 0 writes all), auto (mpio where "
                        "h5py has MPI and there are 2 or more ranks; the default). Both give the same rows; "
                        "the one used is printed and kept in the store's `runs` attribute")
    r.set_defaults(handler=run, ranks=True)
    s = cs.add_parser("status", help="counts by state, failures, throughput, ETA",
                      description="Summarise a store (also while its campaign is running).")
    s.add_argument("store", metavar="STORE.h5")
    s.add_argument("--json", action="store_true", help="one JSON object: tasks, done, failed, running, pending, "
                   "tasks_per_s, eta_s, failures ([task_id, error]), failed_tasks (each with its parameters, rank, "
                   "host and error) (and trials)")
    s.set_defaults(handler=status)
    v = cs.add_parser("verify", help="check every row against its checksum, and the journal's records",
                      description="Check every done or failed row of STORE (and its Monte-Carlo trial rows) "
                                  "against the checksum it carries, every row's parameters against theirs, and every "
                                  "record of STORE.journal against its CRC: one line per damaged row or record (exit 1), or one line saying "
                                  "none is (exit 0). Reads only; also while the campaign runs.")
    v.add_argument("store", metavar="STORE.h5")
    v.add_argument("--json", action="store_true", help="one JSON object: store, rows ([row, task_id]), "
                   "trial_rows ([row, trial task, cell]), journal ([start, end] bytes of damaged stretches), "
                   "param_rows and trial_param_rows (rows whose parameters are damaged, as rows and trial_rows)")
    v.set_defaults(handler=verify)
    rp = cs.add_parser("repair", help="rewrite damaged rows from the journal",
                       description="Rewrite every damaged row of STORE (see `verify`) from its task's entry in "
                                   "STORE.journal, with the values and checksum the run wrote; a damaged row the "
                                   "journal does not hold is set pending (the next run computes it); damaged parameters "
                                   "are rewritten from the campaign's grid (the config the store keeps). Writes only "
                                   "those rows of STORE, under its lock (not while a run holds it).")
    rp.add_argument("store", metavar="STORE.h5")
    rp.add_argument("--json", action="store_true", help="one JSON object: store, repaired (one line per row)")
    rp.set_defaults(handler=repair)


def run(args: argparse.Namespace) -> int:
    from campaign import signals
    signals.install()               # first: a signal from here on stops cleanly (exit 3)
    import gc
    import os
    os.environ.setdefault("OPENBLAS_NUM_THREADS", "1")   # before numpy loads OpenBLAS: one rank a core,
    # and a rank's own BLAS threads would only spin on its neighbour's
    from campaign import config, scheduler
    from common.errors import InputError
    campaign = config.load(args.config)
    from campaign import isolation
    isolation.start_early(campaign)   # the task process, forked before MPI loads; it warms up meanwhile
    store = args.store or campaign.store
    if not store:
        raise InputError(f"{args.config}: no store given (--store, or [campaign] store)")
    parent = os.path.dirname(os.path.abspath(store))
    os.makedirs(parent, exist_ok=True)
    status = scheduler.run(campaign, store, new=args.new, retry_failed=args.retry_failed,
                           progress=not args.quiet, writes=args.write_path)
    from mpi4py import MPI
    if MPI.COMM_WORLD.Get_rank() == 0 and args.json:
        import json
        from campaign.store.reader import summary
        print(json.dumps({"store": store, "exit_status": status, **summary(store)}))
    elif MPI.COMM_WORLD.Get_rank() == 0 and status in (0, 1):
        print(f"campaign: store {store}; look at it with `cortex campaign status {store}`")
    gc.freeze()      # all closed: the interpreter's last collections then skip numba's compiled functions
    return status    # (walking them costs ~0.1 s a process)


def status(args: argparse.Namespace) -> int:
    import json
    from campaign.store.reader import summary
    info = summary(args.store)
    if args.json:
        print(json.dumps(info))
        return 0
    print(f"{args.store}: {info['tasks']} tasks: " + ", ".join(
        f"{info[s]} {s}" for s in ("done", "failed", "running", "pending")))
    if info["tasks_per_s"]:
        eta = f", ETA {info['eta_s']:.0f} s" if info["eta_s"] else ""
        print(f"throughput {info['tasks_per_s']:.2f} task/s{eta}")
    for task in info["failed_tasks"]:
        print(f"failed {task['task_id']} (rank {task['rank']}): {task['error']}")
    if "trials" in info:
        t = info["trials"]
        print(f"Monte-Carlo: {t['trials']} trials: " + ", ".join(
            f"{t[s]} {s}" for s in ("done", "failed", "running", "pending")))
        for err in t["failures"]:
            print(f"failed trials: {err}")
    return 0


def verify(args: argparse.Namespace) -> int:
    import json
    from campaign.store.verify import findings, verify as check
    from common.errors import EXIT_SOME_FAILED
    found = findings(args.store)
    lines = check(args.store, found)
    if args.json:
        print(json.dumps({"store": args.store, **found}))
    else:
        print("\n".join(lines) if lines else f"{args.store}: no damaged row or journal record")
    return EXIT_SOME_FAILED if lines else 0


def repair(args: argparse.Namespace) -> int:
    import json
    from campaign.store.verify import repair as rewrite
    lines = rewrite(args.store)
    if args.json:
        print(json.dumps({"store": args.store, "repaired": lines}))
        return 0
    for line in lines:
        print(line)
    print(f"{args.store}: {len(lines)} damaged rows repaired" if lines else f"{args.store}: no damaged row")
    return 0
