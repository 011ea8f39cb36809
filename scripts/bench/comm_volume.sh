#!/usr/bin/env bash
# Communication volume and synchronisation points per step, Terrace against LAMMPS, counted by
# Open MPI's monitoring components (pml, coll, osc) on oversubscribed ranks (no many-core machine
# needed: the counts do not depend on the cores; only times would).
#
# Scenes: the LJ benchmark (input/lj_bench.nml vs scripts/bench/in.lj_bench, 32,000 atoms) and the
# EAM benchmark (the Terrace deck of scripts/bench/eam_bench.sh vs scripts/bench/in.eam_bench,
# 32,000 Cu atoms). Thermo output every THERMO steps in both codes.
#
# Each (scene, code, ranks) runs four times: S1 and S2 steps with the deck's own neighbour-list
# schedule ("deck"), and S1 and S2 steps with a list that is never rebuilt after the set-up
# ("frozen": Terrace &neighbor every=10**8, check=.false.; LAMMPS neigh_modify every 100000000
# check no). Differences S2 - S1 cancel set-up and finish: the deck difference is the mean step,
# the frozen difference the ordinary step (no rebuild), and their gap divided by the extra builds
# the cost of one rebuild (migration, borders, list). Terrace's LJ scene also runs with LAMMPS's
# schedule of that scene ("every20": &neighbor every=20, check=.false.; the deck checks the
# displacements at every step). Printed by scripts/bench/comm_volume_report.py.
#
# Usage: scripts/bench/comm_volume.sh [TERRACE_BINARY]     (default build/terrace)
# Environment: RANKS (default "2 4 8"), SCENES ("lj eam argon"; argon: Terrace only, below),
#              S1 (20), S2 (100), THERMO (20), LMP (lmp),
#              KEEP=1 keeps the work directory (the .prof files, logs and summaries).
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "${1:-$repo/build/terrace}")"
ranks="${RANKS:-2 4 8}"; scenes="${SCENES:-lj eam argon}"; s1="${S1:-20}"; s2="${S2:-100}"; thermo="${THERMO:-20}"
LMP="${LMP:-lmp}"
for v in "$s1" "$s2" "$thermo"; do
    [[ "$v" =~ ^[0-9]+$ ]] || { echo "comm_volume.sh: S1, S2 and THERMO must be integers" >&2; exit 2; }
done
(( s2 > s1 )) || { echo "comm_volume.sh: S2 must exceed S1" >&2; exit 2; }
for np in $ranks; do
    [[ "$np" =~ ^[0-9]+$ ]] && (( np >= 1 )) || { echo "comm_volume.sh: RANKS must be positive integers" >&2; exit 2; }
    if [[ " $scenes " == *" argon "* ]] && (( (np & (np - 1)) != 0 )); then
        echo "comm_volume.sh: the argon scene needs power-of-two rank counts (RANKS), got $np" >&2; exit 2
    fi
done
[[ -x "$terrace" ]] || { echo "comm_volume.sh: no Terrace binary at $terrace" >&2; exit 2; }
work="$(mktemp -d "${TMPDIR:-/tmp}/comm_volume.XXXXXX")"
if [[ "${KEEP:-0}" == 1 ]]; then echo "work directory: $work"; else trap 'rm -rf "$work"' EXIT; fi
ncores="$(nproc)"; export OMP_NUM_THREADS=1
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
frozen_every=100000000

echo "Communication per step, Terrace vs LAMMPS, counted by Open MPI's monitoring components"
echo "machine : $(lscpu | sed -n 's/^Model name: *//p' | head -1) ($ncores cores visible; ranks oversubscribed)"
echo "MPI     : $(mpirun --version 2>&1 | head -1)"
echo "LAMMPS  : $("$LMP" -h 2>/dev/null | sed -n 's/^Large-scale Atomic\/Molecular Massively Parallel Simulator - *//p' | head -1)"
echo "date    : $(date -u '+%Y-%m-%d %H:%M:%S UTC')"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)   binary: $terrace"
echo "steps   : S1=$s1, S2=$s2, thermo every $thermo; ranks: $ranks"
echo

# Terrace decks: NAME MODE NSTEPS -> file
terrace_deck() {
    local scene=$1 mode=$2 n=$3 f=$4 nb="&neighbor skin=0.3 /"
    if [[ $scene == lj ]]; then
        [[ $mode == frozen ]] && nb="&neighbor skin=0.3, every=$frozen_every, check=.false. /"
        [[ $mode == every20 ]] && nb="&neighbor skin=0.3, every=20, check=.false. /"
        sed -e "s/n_steps=[0-9]*/n_steps=$n/" -e "s/thermo_every=[0-9]*/thermo_every=$thermo/" \
            -e "s|^&neighbor .*|${nb//&/\\&}|" "$repo/input/lj_bench.nml" > "$f"
    else
        nb="&neighbor skin=1.0 /"
        [[ $mode == frozen ]] && nb="&neighbor skin=1.0, every=$frozen_every, check=.false. /"
        cat > "$f" <<NML
&run units='metal', dimension=3, n_steps=$n, seed=376847 /
&system lattice='fcc', lattice_constant=3.615, cells=20,20,20, periodic=.true.,.true.,.true., temperature=1600.0 /
&potential style='eam', file='/usr/share/lammps/potentials/Cu_u3.eam' /
&integrator style='velocity_verlet', dt=0.005 /
$nb
&output thermo_every=$thermo /
NML
    fi
}
# The 100 ns argon job's scene (input/argon_nvt_100ns.nml: LJ argon at 94.4 K, CSVR, 10 fs, skin 1 A),
# 864 atoms per rank: the 6 x 6 x 6 fcc lattice doubled along x, y, z in turn per doubling of the
# ranks (power-of-two rank counts); thermo every THERMO steps, no trajectory or checkpoint.
argon_deck() {
    local mode=$1 n=$2 np=$3 f=$4 k c=(6 6 6) i=0 nb="&neighbor skin=1.0 /"
    for ((k = np; k > 1; k /= 2)); do c[i]=$((2 * c[i])); i=$(((i + 1) % 3)); done
    [[ $mode == frozen ]] && nb="&neighbor skin=1.0, every=$frozen_every, check=.false. /"
    cat > "$f" <<NML
&run units='metal', dimension=3, n_steps=$n, seed=1964 /
&system lattice='fcc', lattice_constant=5.780150, cells=${c[0]},${c[1]},${c[2]}, periodic=.true.,.true.,.true.,
        mass=39.948, temperature=94.4 /
&potential style='lj', epsilon=0.0103408116, sigma=3.4, cutoff=8.5, shift=.true. /
&integrator style='velocity_verlet', dt=0.01 /
$nb
&thermostat style='csvr', temperature=94.4, damping=1.0 /
&output thermo_every=$thermo /
NML
}
lammps_input() {
    local scene=$1 mode=$2 f=$3 src="$here/in.lj_bench"
    [[ $scene == eam ]] && src="$here/in.eam_bench"
    if [[ $mode == frozen ]]; then
        sed -e "s/^thermo .*/thermo          $thermo/" \
            -e "s/^neigh_modify .*/neigh_modify    delay 0 every $frozen_every check no/" "$src" > "$f"
    else
        sed -e "s/^thermo .*/thermo          $thermo/" "$src" > "$f"
    fi
}

monitor=(--mca pml_monitoring_enable 2 --mca pml_monitoring_enable_output 3)
: > "$work/runs.tsv"
start=$SECONDS
for scene in $scenes; do
    for np in $ranks; do
        codes="terrace lammps"
        [[ $scene == argon ]] && codes=terrace
        for code in $codes; do
            modes="deck frozen"
            [[ $scene == lj && $code == terrace ]] && modes="deck every20 frozen"
            for mode in $modes; do
                for n in "$s1" "$s2"; do
                    d="$work/${scene}_${code}_${mode}_${np}_$n"; mkdir -p "$d"
                    if [[ $code == terrace ]]; then
                        if [[ $scene == argon ]]; then
                            argon_deck "$mode" "$n" "$np" "$d/run.nml"
                        else
                            terrace_deck "$scene" "$mode" "$n" "$d/run.nml"
                        fi
                        (cd "$d" && mpirun --oversubscribe -np "$np" "${monitor[@]}" \
                            --mca pml_monitoring_filename "$d/mon" "$terrace" run.nml > screen.log 2>&1) ||
                            { echo "comm_volume.sh: Terrace failed in $d" >&2; tail -5 "$d/screen.log" >&2; exit 1; }
                    else
                        lammps_input "$scene" "$mode" "$d/in.run"
                        (cd "$d" && mpirun --oversubscribe -np "$np" "${monitor[@]}" \
                            --mca pml_monitoring_filename "$d/mon" "$LMP" -in in.run -var nsteps "$n" \
                            -log log.lammps -screen none > screen.log 2>&1) ||
                            { echo "comm_volume.sh: LAMMPS failed in $d" >&2; tail -5 "$d/log.lammps" >&2; exit 1; }
                    fi
                    printf '%s\t%s\t%s\t%s\t%s\t%s\n' "$scene" "$code" "$mode" "$np" "$n" "$d" >> "$work/runs.tsv"
                done
            done
        done
        echo "  $scene on $np ranks done ($((SECONDS - start)) s so far)"
    done
done
echo
PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 "$here/comm_volume_report.py" "$work/runs.tsv"
