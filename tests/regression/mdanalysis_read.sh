#!/usr/bin/env bash
# An independent H5MD reader: MDAnalysis (installed from PyPI into a virtual environment outside the
# repository) opens Terrace trajectories of a 3-D periodic LJ liquid (reduced units, 2 ranks, with
# forces) and of a free 147-atom argon cluster (metal units, read with MDAnalysis's unit handling);
# every frame it returns (positions, velocities, forces, box, time, step) must equal what h5py reads
# from the file to MDAnalysis's float32 rounding, and the file must match the engine's own text
# outputs: the forces file (step 0) and the final-atoms file (last frame, positions and velocities).
# Both also open in one line, mda.Universe('X.topology.data', 'X.h5', format='H5MD', convert_units=False),
# with the topology Terrace writes beside a 3-D trajectory (types and masses = the file's species and
# mass), and through terrace_tools.h5md.universe('X.h5'): positions = h5py's in every frame.
# A 2-D file is also offered to MDAnalysis, which refuses 2-D boxes (reported, not failed).
#
# The virtual environment ($TERRACE_VENV, default ~/.cache/terrace-venv; Debian's python3 with
# --system-site-packages, so numpy and h5py come from Debian) is created once and reused. When
# MDAnalysis cannot be installed (no network, no python3-venv) the test exits 77: SKIPPED in CTest.
# Usage: tests/regression/mdanalysis_read.sh TERRACE_BINARY OUTDIR
set -euo pipefail
[[ $# -eq 2 ]] || { echo "usage: $0 TERRACE_BINARY OUTDIR" >&2; exit 2; }
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
terrace="$(realpath "$1")"; out="$2"
venv="${TERRACE_VENV:-$HOME/.cache/terrace-venv}"
spec="${TERRACE_MDANALYSIS:-MDAnalysis==2.11.0}"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1

rm -rf "$out"; mkdir -p "$out"

# ---- MDAnalysis in a reusable virtual environment
if ! "$venv/bin/python" -c 'import MDAnalysis' > /dev/null 2>&1; then
    if ! /usr/bin/python3 -c 'import ensurepip, venv' > /dev/null 2>&1; then
        echo "SKIPPED: /usr/bin/python3 cannot create virtual environments (Debian package python3-venv;" \
             "bash scripts/install_deps.sh installs it)"
        exit 77
    fi
    echo "creating $venv and installing $spec from PyPI (once; later runs reuse it)"
    rm -rf "$venv"; mkdir -p "$(dirname "$venv")"
    if ! { /usr/bin/python3 -m venv --system-site-packages "$venv" &&
           timeout 900 "$venv/bin/pip" install --disable-pip-version-check --timeout 20 --retries 1 -q "$spec"; } \
           > "$out/pip.log" 2>&1; then
        rm -rf "$venv"
        echo "SKIPPED: could not install $spec from PyPI (no network?); $out/pip.log ends with:"
        tail -3 "$out/pip.log"
        exit 77
    fi
fi
"$venv/bin/python" -c 'import MDAnalysis, h5py; print("MDAnalysis", MDAnalysis.__version__, "h5py", h5py.__version__)'

# ---- trajectories and the engine's own outputs
cd "$out"
# the liquid starts from frame 3 of a melting run (forces at its step 0 are not those of a lattice)
cat > melt.nml <<'NML'
&run units='lj', dimension=3, n_steps=40, seed=4242 /
&system lattice='fcc', density=0.8442, cells=6,6,6, periodic=.true.,.true.,.true., mass=1.0, temperature=1.44 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=20, thermo_file='melt.csv', trajectory_file='melt.h5', trajectory_every=20 /
NML
cat > liquid.nml <<'NML'
! 3-D periodic LJ liquid in reduced units (no unit attributes), 864 atoms, 50 steps on 2 ranks
&run units='lj', dimension=3, n_steps=50, seed=4242 /
&system read_h5md='melt.h5', h5md_frame=3, periodic=.true.,.true.,.true., mass=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=10, thermo_file='liquid.csv', trajectory_file='liquid.h5', trajectory_every=10,
        trajectory_fields='position velocity force image', forces_file='liquid_forces.txt',
        final_atoms_file='liquid_final.atoms' /
NML
cat > cluster.nml <<NML
! free 147-atom argon icosahedron at 40 K in metal units, Verlet 10 fs, 50 steps (default fields)
&run units='metal', dimension=3, n_steps=50, seed=147 /
&system atoms_file='$repo/input/argon_ico147.atoms', periodic=.false.,.false.,.false., mass=39.951,
        temperature=40.0 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=8.525, shift=.true. /
&integrator style='velocity_verlet', dt=0.01 /
&neighbor skin=1.0 /
&output thermo_every=10, thermo_file='cluster.csv', trajectory_file='cluster.h5', trajectory_every=10,
        final_atoms_file='cluster_final.atoms' /
NML
cat > flat.nml <<NML
&run units='metal', dimension=2, n_steps=20, seed=1 /
&system atoms_file='$repo/input/argon_frozen_2d.atoms', periodic=.false.,.false., mass=39.951 /
&potential style='lj', epsilon=0.010323577, sigma=3.41, cutoff=0.0 /
&integrator style='velocity_verlet', dt=0.01 /
&output thermo_every=10, thermo_file='flat.csv', trajectory_file='flat.h5', trajectory_every=10 /
NML
timeout 300 "$terrace" melt.nml > melt.log 2>&1 || { echo "FAIL: melt run"; tail -3 melt.log; exit 1; }
timeout 300 mpirun --oversubscribe -np 2 "$terrace" liquid.nml > liquid.log 2>&1 || { echo "FAIL: liquid run"; tail -3 liquid.log; exit 1; }
for deck in cluster flat; do
    timeout 300 "$terrace" $deck.nml > $deck.log 2>&1 || { echo "FAIL: $deck run"; tail -3 $deck.log; exit 1; }
done

# ---- MDAnalysis against h5py and the engine's text outputs
PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" "$venv/bin/python" - <<'PY'
import sys
import warnings
import h5py
import numpy as np
import MDAnalysis as mda

warnings.filterwarnings("ignore")
ok = True
F32 = 2.0 ** -24          # float32 rounding: MDAnalysis keeps coordinates as float32


def check(name, cond):
    global ok
    print(("ok   " if cond else "FAIL ") + name)
    ok = ok and bool(cond)


def rel32(a, b):
    """max |a - b| in units of float32 rounding of b (<= 1 means equal to float32 round-off)."""
    scale = np.maximum(np.abs(b), np.finfo(np.float32).tiny)
    return float((np.abs(a - b) / (F32 * scale)).max())


def table(path):
    return np.loadtxt(path, comments="#")


for stem, periodic, units in (("liquid", True, False), ("cluster", False, True)):
    print(f"--- {stem}.h5 ({'3-D periodic, reduced units' if periodic else '3-D free cluster, metal units'})")
    f = h5py.File(f"{stem}.h5", "r")
    p = f["particles/all"]
    # MDAnalysis infers a minimal topology only from a particles group named 'trajectory' (Terrace's,
    # like LAMMPS's, is 'all'): give it an empty topology of the right size. Reduced-unit files carry
    # no unit attributes, which MDAnalysis accepts only with convert_units=False.
    u = mda.Universe.empty(p["id"].shape[0], trajectory=False)
    u.load_new(f"{stem}.h5", format="H5MD", convert_units=units)
    traj = u.trajectory
    if units:
        check(f"MDAnalysis reads the metal unit attributes: {traj.units}",
              traj.units == {"time": "ps", "length": "Angstrom", "velocity": "Angstrom/ps", "force": None})
    fields = [k for k in ("position", "velocity", "force") if k in p]
    n, nf = p["position/value"].shape[1], p["position/value"].shape[0]
    check(f"MDAnalysis sees {len(u.atoms)} atoms and {traj.n_frames} frames (h5py: {n}, {nf}); fields {fields}",
          len(u.atoms) == n and traj.n_frames == nf)
    worst = dict.fromkeys(fields, 0.0)
    box_ok = time_ok = True
    for ts in traj:
        k = ts.frame
        for name in fields:
            arr = getattr(ts, {"position": "positions", "velocity": "velocities", "force": "forces"}[name])
            worst[name] = max(worst[name], rel32(arr.astype(np.float64), p[f"{name}/value"][k]))
        edges = p["box/edges/value"][k]
        box_ok &= np.allclose(ts.dimensions[:3], edges, rtol=F32, atol=0) and np.all(ts.dimensions[3:] == 90)
        time_ok &= ts.time == p["position/time"][k] and ts.data["step"] == p["position/step"][k]
    for name, w in worst.items():
        check(f"{name}: every frame equals h5py's to float32 rounding (max {w:.2f} x 2^-24 relative)", w <= 1.0)
    check(f"box: MDAnalysis dimensions = box/edges/value {p['box/edges/value'][0]} with 90-degree angles", box_ok)
    check(f"time and step of every frame equal position/time, step (last t = {p['position/time'][-1]})", time_ok)
    boundary = [b.decode() if isinstance(b, bytes) else str(b) for b in p["box"].attrs["boundary"]]
    check(f"box/boundary = {boundary}", boundary == (["periodic"] * 3 if periodic else ["none"] * 3))

    # the engine's own outputs: forces at step 0, final positions and velocities
    if "force" in fields:
        forces = table(f"{stem}_forces.txt")
        traj[0]
        check("forces file (step 0) ids are those of the trajectory",
              np.array_equal(forces[:, 0].astype(np.int64), p["id"][:]))
        w = rel32(traj.ts.forces.astype(np.float64), forces[:, 1:4])
        check(f"frame 0 forces (MDAnalysis) = forces file to float32 rounding ({w:.2f})", w <= 1.0)
        check("frame 0 forces (h5py) = forces file exactly", np.array_equal(p["force/value"][0], forces[:, 1:4]))
    final = table(f"{stem}_final.atoms")
    traj[-1]
    x, v = traj.ts.positions.astype(np.float64), traj.ts.velocities.astype(np.float64)
    if periodic:
        L = p["box/edges/value"][-1]
        d = x - final[:, 1:4]
        d -= L * np.round(d / L)           # the final-atoms file wraps periodic coordinates
        dx = float(np.abs(d).max())
        check(f"last frame positions = final-atoms file modulo the box (max |dx| {dx:.2e}; float32 "
              f"rounding of |x| <= {F32 * L.max():.1e})", dx <= 1.01 * F32 * L.max())
        xh = p["position/value"][-1] - final[:, 1:4]
        xh -= L * np.round(xh / L)
        check(f"last frame positions (h5py) = final-atoms file modulo the box ({np.abs(xh).max():.1e})",
              np.abs(xh).max() <= 1e-12 * L.max())
    else:
        w = rel32(x, final[:, 1:4])
        check(f"last frame positions = final-atoms file to float32 rounding ({w:.2f})", w <= 1.0)
        check("last frame positions (h5py) = final-atoms file exactly",
              np.array_equal(p["position/value"][-1], final[:, 1:4]))
    w = rel32(v, final[:, 4:7])
    check(f"last frame velocities = final-atoms file to float32 rounding ({w:.2f})", w <= 1.0)
    check("last frame velocities (h5py) = final-atoms file exactly",
          np.array_equal(p["velocity/value"][-1], final[:, 4:7]))
    f.close()

# ---- one line: the topology Terrace writes beside a 3-D trajectory, and terrace_tools' helper
from terrace_tools import h5md as th5

for stem, metal in (("liquid", False), ("cluster", True)):
    print(f"--- one-line Universe of {stem}.h5 ({'metal' if metal else 'LJ'} units)")
    u = mda.Universe(f"{stem}.topology.data", f"{stem}.h5", format="H5MD", convert_units=False)
    helper = th5.universe(f"{stem}.h5")
    with h5py.File(f"{stem}.h5", "r") as f:
        p = f["particles/all"]
        nf = p["position/value"].shape[0]
        check(f"mda.Universe('{stem}.topology.data', '{stem}.h5', format='H5MD', convert_units=False): "
              f"{len(u.atoms)} atoms, {u.trajectory.n_frames} frames",
              len(u.atoms) == p["id"].shape[0] and u.trajectory.n_frames == nf)
        check("its masses are /particles/all/mass, its types /particles/all/species",
              np.array_equal(u.atoms.masses, p["mass"][()]) and
              np.array_equal(u.atoms.types.astype(int), p["species"][()]))
        check("terrace_tools.h5md.universe: the same atoms, masses and types",
              np.array_equal(helper.atoms.masses, u.atoms.masses) and
              np.array_equal(helper.atoms.types, u.atoms.types))
        check(f"helper converts units only where MDAnalysis knows them all: {helper.trajectory.convert_units}",
              helper.trajectory.convert_units == metal)
        wu = wh = 0.0
        for ts, th in zip(u.trajectory, helper.trajectory):
            ref = p["position/value"][ts.frame]
            wu = max(wu, rel32(ts.positions.astype(np.float64), ref))
            wh = max(wh, rel32(th.positions.astype(np.float64), ref))
        check(f"every frame's positions equal h5py's to float32 rounding (one line {wu:.2f}, helper {wh:.2f})",
              wu <= 1.0 and wh <= 1.0)
        import shutil
        shutil.copy(f"{stem}.h5", f"{stem}_alone.h5")       # no topology beside it: built from the file
        alone = th5.universe(f"{stem}_alone.h5")
        check("terrace_tools.h5md.universe without the topology file: masses and types from the H5MD file",
              np.array_equal(alone.atoms.masses, p["mass"][()]) and
              np.array_equal(alone.atoms.types.astype(int), p["species"][()]) and
              rel32(alone.trajectory[-1].positions.astype(np.float64), p["position/value"][-1]) <= 1.0)
        if metal:
            m = mda.Universe(f"{stem}.topology.data", f"{stem}.h5", format="H5MD")
            check(f"metal units without forces also open with unit conversion: {m.trajectory.units}",
                  m.trajectory.units["length"] == "Angstrom" and m.trajectory.units["time"] == "ps")

print("--- flat.h5 (2-D)")
try:
    mda.Universe.empty(7).load_new("flat.h5", format="H5MD", convert_units=False)
    print("note: this MDAnalysis opens 2-D H5MD files")
except ValueError as e:
    print(f"note: MDAnalysis refuses the 2-D file, as documented: {e}")
print("PASS" if ok else "FAIL")
sys.exit(0 if ok else 1)
PY
