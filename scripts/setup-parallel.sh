#!/usr/bin/env bash
# The parallel-HDF5 stack in VENVDIR: Debian's MPICH and parallel HDF5, mpi4py
# (binary wheel, run against Debian's MPICH), h5py compiled with MPI, and this
# project editable with its test extras (never the `mpich` extra: one MPI only).
#
#   bash scripts/setup-parallel.sh VENVDIR      (PYTHON=python3 by default)
#
# Writes VENVDIR/bin/with-mpi, which runs a command in that stack:
#   VENVDIR/bin/with-mpi mpiexec -n 2 VENVDIR/bin/python -m pytest --with-mpi -m mpi
#
# Idempotent: a stamp newer than this script and pyproject.toml makes it a fast
# no-op. Exit status 77 means "cannot be installed here" (Debian packages
# missing and not root); the Makefile reports that as a skip.
#
# Why the pieces: mpi4py's binary wheel opens `libmpi.so.12` (MPICH's ABI);
# Debian calls the same library `libmpich.so.12`, so VENVDIR/lib/mpi holds a
# link under that name and with-mpi puts it on LD_LIBRARY_PATH. h5py is built
# without build isolation, against the numpy and mpi4py already installed
# (with isolation pip compiles mpi4py from source: tens of GiB of memory).
set -euo pipefail

venv=${1:?usage: setup-parallel.sh VENVDIR}
python=${PYTHON:-python3}
root=$(cd "$(dirname "$0")/.." && pwd)
stamp=$venv/.setup-parallel-done

if [[ -f $stamp && $stamp -nt $root/pyproject.toml && $stamp -nt $0 && -x $venv/bin/with-mpi ]]; then
    exit 0
fi

# 1. Debian packages (root only).
debs=(mpich libhdf5-mpich-dev pkg-config build-essential python3-dev python3-venv)
missing=()
for p in "${debs[@]}"; do
    dpkg-query -W -f='${Status}' "$p" 2>/dev/null | grep -q '^install ok installed' || missing+=("$p")
done
if ((${#missing[@]})); then
    if [[ $(id -u) != 0 ]] || ! command -v apt-get >/dev/null; then
        echo "setup-parallel: needs Debian packages ${missing[*]} (apt-get as root); not installing the parallel-HDF5 stack"
        exit 77
    fi
    echo "setup-parallel: apt-get install ${missing[*]}"
    export DEBIAN_FRONTEND=noninteractive
    apt-get -o DPkg::Lock::Timeout=600 update -qq
    apt-get -o DPkg::Lock::Timeout=600 install -y -qq --no-install-recommends "${missing[@]}" >/dev/null
fi

# awk reads to the end (no early `exit`): under pipefail an early exit can kill ldconfig with
# SIGPIPE mid-write and fail this line with status 141, depending on timing.
libmpich=$(ldconfig -p | awk '$1 == "libmpich.so.12" && !found {print $NF; found = 1}')
[[ -n $libmpich ]] || { echo "setup-parallel: libmpich.so.12 not found after installing mpich" >&2; exit 1; }

# 2. The venv, the MPI link and the wrapper.
[[ -x $venv/bin/python ]] || "$python" -m venv "$venv"
venv=$(cd "$venv" && pwd)
mkdir -p "$venv/lib/mpi"
ln -sfn "$libmpich" "$venv/lib/mpi/libmpi.so.12"
# hydra finds hydra_pmi_proxy beside the path it was started as: exec it, not a link.
rm -f "$venv/bin/mpiexec"
printf '#!/bin/sh\nexec /usr/bin/mpiexec.mpich "$@"\n' > "$venv/bin/mpiexec"
chmod +x "$venv/bin/mpiexec"
cat > "$venv/bin/with-mpi" <<'EOF'
#!/bin/sh
# Run a command with Debian's MPICH (libmpi.so.12 -> libmpich.so.12) and its mpiexec.
venv=$(cd "$(dirname "$0")/.." && pwd)
export LD_LIBRARY_PATH="$venv/lib/mpi${LD_LIBRARY_PATH:+:$LD_LIBRARY_PATH}"
export PATH="$venv/bin:$PATH"
exec "$@"
EOF
chmod +x "$venv/bin/with-mpi"
pip=("$venv/bin/with-mpi" "$venv/bin/python" -m pip -q --disable-pip-version-check)

# 3. Build requirements of h5py, then h5py itself against parallel HDF5.
"${pip[@]}" install --upgrade pip
"${pip[@]}" install --only-binary=mpi4py 'numpy>=1.26' 'mpi4py>=4.0' 'cython>=3,<4' pkgconfig 'setuptools>=77' wheel
if ! "$venv/bin/with-mpi" "$venv/bin/python" -c 'import h5py, sys; sys.exit(not h5py.get_config().mpi)' 2>/dev/null; then
    echo "setup-parallel: building h5py against Debian's parallel HDF5 (a few minutes)"
    # its C extensions compiled on every CPU (setuptools' build_ext --parallel, through the extra
    # config file setuptools reads from DIST_EXTRA_CONFIG): 92 s instead of 153 s on two cores;
    # at -O1 without debug information (CFLAGS, unless set) half the CPU of the default -g -O2
    # (101 s against 200 s): h5py's wrappers only pass calls on to Debian's optimised HDF5
    build_cfg=$(mktemp)
    trap 'rm -f "$build_cfg"' EXIT     # also where the build fails or is interrupted
    printf '[build_ext]\nparallel = %s\n' "$(nproc)" > "$build_cfg"
    DIST_EXTRA_CONFIG=$build_cfg HDF5_MPI=ON CC=mpicc HDF5_PKGCONFIG_NAME=hdf5-mpich CFLAGS=${CFLAGS:--O1 -g0} \
        "${pip[@]}" install --force-reinstall --no-deps --no-binary=h5py --no-build-isolation --no-cache-dir 'h5py>=3.10'
fi

# 4. The project, editable; h5py and mpi4py are already satisfied and stay.
"${pip[@]}" install --no-build-isolation -e "$root[test]"

# 5. Check: one MPI library in the process, Debian's, shared by mpi4py and h5py;
# the project's packages importable from anywhere (as the `cortex` script does).
(cd / && "$venv/bin/with-mpi" "$venv/bin/python" - "$libmpich") <<'EOF'
import os, sys
from mpi4py import MPI
import h5py
import analysis, campaign, cortex, solver  # noqa: F401
maps = open("/proc/self/maps").read().split()
libs = {os.path.realpath(p) for p in maps if "/libmpi" in p}
want = os.path.realpath(sys.argv[1])
assert libs == {want}, f"MPI libraries loaded: {sorted(libs)}, expected only {want}"
assert h5py.get_config().mpi, "h5py was built without MPI"
print(f"setup-parallel: ok: {MPI.Get_library_version().splitlines()[0].strip()}, "
      f"h5py {h5py.version.version} with MPI, HDF5 {h5py.version.hdf5_version}")
EOF
touch "$stamp"
