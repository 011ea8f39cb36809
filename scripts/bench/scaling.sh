#!/usr/bin/env bash
# Parallel scaling, 1 to P ranks: Terrace (velocity Verlet and energy stepping) next to LAMMPS on the
# same cores, for the LJ benchmark scene and LAMMPS's in.eam scene. Strong scaling: 32,000 atoms on
# 1..P ranks. Weak scaling: 32,000 atoms per rank (20 x 20 x 20 fcc cells per rank, the box doubled
# along its shortest side for each doubling of the ranks). One run per point (the loop time each code
# prints); LAMMPS rebuilds its list as Terrace does (every step when an atom has moved skin/2:
# neigh_modify every 1 delay 0 check yes), so both build about as often. Every run starts from the
# lattice, as the benchmarks do. (Before commit 06b035c energy stepping took about 5 ray evaluations
# per event there, at 32,000 LJ atoms; now about 1.)
#
# Usage: scripts/bench/scaling.sh [RANKS [OUTDIR]]     RANKS default 1,2,4,8,16; OUTDIR default a temp dir
# Environment: TERRACE (binary, default build/terrace), LMP (default lmp), MPIRUN (default mpirun),
#   EAM_FILE (default /usr/share/lammps/potentials/Cu_u3.eam), MPI_FLAGS (extra mpirun flags; default
#   binds each rank to a core), LJ_STEPS (300), LJ_EVENTS (150), EAM_STEPS (100), EAM_EVENTS (50),
#   PARTS ("lj eam"), KINDS ("strong weak"), BASELINE (a second Terrace binary: above one rank each
#   Terrace run is then also made with it just before, as code terrace-vv-base or terrace-es-base; the
#   report gives the baseline's loop time over the binary's).
# Prints one table per scene and kind (scripts/bench/scaling_report.py: loop seconds, speed-up (strong)
# or efficiency (weak) against one rank, Terrace's slowest rank's Comm and Search times). Raw rows go
# to OUTDIR/scaling.csv, each run's log to OUTDIR/SCENE_KIND_npP/; scaling_report.py OUTDIR --phases
# --figure F.png gives the per-phase tables and the figure.
# Only meaningful on a machine with at least as many free cores as the largest rank count.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
# the run summary's figures (scripts/terrace_tools)
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }
ranks="${1:-1,2,4,8,16}"; out="${2:-$(mktemp -d)}"; mkdir -p "$out"; out="$(cd "$out" && pwd)"
terrace="$(realpath "${TERRACE:-$repo/build/terrace}")"; lmp="${LMP:-lmp}"; mpirun="${MPIRUN:-mpirun}"
eam_file="${EAM_FILE:-/usr/share/lammps/potentials/Cu_u3.eam}"
lj_steps="${LJ_STEPS:-300}"; lj_events="${LJ_EVENTS:-150}"; eam_steps="${EAM_STEPS:-100}"; eam_events="${EAM_EVENTS:-50}"
parts="${PARTS:-lj eam}"; kinds="${KINDS:-strong weak}"
export OMP_NUM_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# shellcheck source=ranks_lib.sh
source "$here/ranks_lib.sh"; ranks_setup "$ranks"
[[ -x "$terrace" ]] || { echo "scaling.sh: no Terrace binary at $terrace (build it: bash scripts/build.sh)" >&2; exit 1; }
baseline=""
if [[ -n "${BASELINE:-}" ]]; then
    baseline="$(realpath "$BASELINE")"
    [[ -x "$baseline" ]] || { echo "scaling.sh: BASELINE $BASELINE is not an executable" >&2; exit 1; }
fi
command -v "$lmp" > /dev/null || { echo "scaling.sh: no LAMMPS binary '$lmp' (Debian: lammps)" >&2; exit 1; }
[[ -r "$eam_file" ]] || { echo "scaling.sh: cannot read EAM_FILE $eam_file (Debian: lammps-data)" >&2; exit 1; }

echo "Parallel scaling: Terrace (velocity Verlet, energy stepping) and LAMMPS, ranks $ranks"
echo "machine : $(lscpu | sed -n 's/^Model name: *//p' | head -1); $ncores logical CPUs, $phys physical cores"
echo "date    : $(date -u '+%Y-%m-%d %H:%M:%S UTC')"
echo "commit  : ${BUNDLE_COMMIT:-$(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)}"
echo "terrace : $terrace${baseline:+ (codes terrace-*-base: $baseline)}"
echo "lammps  : $("$lmp" -h 2>/dev/null | sed -n 's/^Large-scale Atomic\/Molecular Massively Parallel Simulator - //p' | head -1)"
echo "mpirun  : $("$mpirun" --version 2>&1 | head -1); flags: $MPI_FLAGS"
echo "runs    : LJ $lj_steps Verlet steps, $lj_events events; EAM $eam_steps steps, $eam_events events; one run per point"
echo

# Weak scaling's box: 20 cells per rank and axis, doubled as ranks_lib.sh's weak_factors says.
weak_cells() { local a b c; read -r a b c <<< "$(weak_factors "$1")"; echo "$((20 * a)) $((20 * b)) $((20 * c))"; }

terrace_deck() {  # scene nx ny nz integrator n
    local scene=$1 nx=$2 ny=$3 nz=$4 integ=$5 n=$6
    if [[ $scene == lj ]]; then
        cat <<NML
&run units='lj', dimension=3, n_steps=$n, seed=87287 /
&system lattice='fcc', density=0.8442, cells=$nx,$ny,$nz, periodic=.true.,.true.,.true., mass=1.0, temperature=1.44 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /
$integ
&neighbor skin=0.3 /
&output thermo_every=$n, thermo_file='' /
NML
    else
        cat <<NML
&run units='metal', dimension=3, n_steps=$n, seed=376847 /
&system lattice='fcc', lattice_constant=3.615, cells=$nx,$ny,$nz, periodic=.true.,.true.,.true., temperature=1600.0 /
&potential style='eam', file='$eam_file' /
$integ
&neighbor skin=1.0 /
&output thermo_every=$n, thermo_file='' /
NML
    fi
}

lammps_input() {  # scene nx ny nz n
    local scene=$1 nx=$2 ny=$3 nz=$4 n=$5 units lattice model
    if [[ $scene == lj ]]; then
        units=lj; lattice=0.8442
        model="mass 1 1.0
velocity all create 1.44 87287 loop geom
pair_style lj/cut 2.5
pair_modify shift yes
pair_coeff 1 1 1.0 1.0 2.5
neighbor 0.3 bin"
    else
        units=metal; lattice=3.615
        model="pair_style eam
pair_coeff 1 1 $eam_file
velocity all create 1600.0 376847 loop geom
neighbor 1.0 bin"
    fi
    cat <<LMP
units $units
atom_style atomic
lattice fcc $lattice
region box block 0 $nx 0 $ny 0 $nz
create_box 1 box
create_atoms 1 box
$model
neigh_modify every 1 delay 0 check yes
fix 1 all nve
timestep 0.005
thermo $n
run $n
LMP
}

csv="$out/scaling.csv"
echo "scene,kind,ranks,atoms,code,n,loop_s,comm_max_s,search_max_s,rays_per_event" > "$csv"
phase_max() { figure "$2" "timing/phases/$1/max_s"; }   # PHASE SUMMARY

for scene in $parts; do
    if [[ $scene == lj ]]; then vv="&integrator style='velocity_verlet', dt=0.005 /"; nvv=$lj_steps; nes=$lj_events
        es="&integrator style='energy_stepping', terrace_height=0.3 /"
    else vv="&integrator style='velocity_verlet', dt=0.005 /"; nvv=$eam_steps; nes=$eam_events
        es="&integrator style='energy_stepping', terrace_height=0.03 /"; fi
    for kind in $kinds; do
        for p in "${plist[@]}"; do
            if [[ $kind == strong ]]; then read -r nx ny nz <<< "20 20 20"; else read -r nx ny nz <<< "$(weak_cells "$p")"; fi
            natoms=$((4 * nx * ny * nz))
            d="$out/${scene}_${kind}_np$p"; mkdir -p "$d"; cd "$d"
            codes="terrace-vv terrace-es lammps"
            [[ -n "$baseline" && $p -gt 1 ]] && codes="terrace-vv-base terrace-vv terrace-es-base terrace-es lammps"
            for code in $codes; do
                comm=""; search=""; rays=""
                case $code in
                terrace-vv*|terrace-es*)
                    bin="$terrace"; [[ $code == *-base ]] && bin="$baseline"
                    if [[ $code == terrace-vv* ]]; then terrace_deck "$scene" "$nx" "$ny" "$nz" "$vv" "$nvv" > "$code.nml"; n=$nvv
                    else terrace_deck "$scene" "$nx" "$ny" "$nz" "$es" "$nes" > "$code.nml"; n=$nes; fi
                    # shellcheck disable=SC2086
                    if ! "$mpirun" $MPI_FLAGS -np "$p" "$bin" "$code.nml" > "$code.log" 2>&1; then
                        echo "FAILED: $scene $kind $code np $p (log $d/$code.log):"; tail -5 "$code.log"; continue; fi
                    loop=$(figure "$code.summary.json" timing/loop_time_s)
                    comm=$(phase_max Comm "$code.summary.json"); search=$(phase_max Search "$code.summary.json")
                    rays=$(figure "$code.summary.json" energy_stepping/ray_evaluations_per_event 2> /dev/null || true) ;;
                lammps)
                    lammps_input "$scene" "$nx" "$ny" "$nz" "$nvv" > in.lmp; n=$nvv
                    # shellcheck disable=SC2086
                    if ! "$mpirun" $MPI_FLAGS -np "$p" "$lmp" -in in.lmp -log lammps.log -screen none > lammps.out 2>&1; then
                        echo "FAILED: $scene $kind lammps np $p (log $d/lammps.log):"; tail -5 lammps.log; continue; fi
                    loop=$(sed -n 's/^Loop time of \([0-9.eE+-]*\) on.*/\1/p' lammps.log | tail -1) ;;
                esac
                echo "$scene,$kind,$p,$natoms,$code,$n,$loop,$comm,$search,$rays" >> "$csv"
                printf '  %-4s %-6s np %2d  %7d atoms  %-10s %4d  loop %9.3f s\n' "$scene" "$kind" "$p" "$natoms" "$code" "$n" "$loop"
            done
            cd "$out"
        done
    done
done

echo
PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" python3 "$here/scaling_report.py" "$out"
