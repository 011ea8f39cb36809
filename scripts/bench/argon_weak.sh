#!/usr/bin/env bash
# Weak scaling of the 100 ns argon job (input/argon_nvt_100ns.nml): 864 atoms of Rahman's liquid per
# rank, 1 to P ranks. The liquid that input/argon_nvt.nml leaves is tiled P times (doubled along the
# shortest axis for each factor 2 of P, as scaling.sh's weak boxes), and the job's deck runs on it as
# it is (CSVR, 10 fs, thermo and a frame of x and v every 10 ps, exact list) and with the mixed kernel
# at GROMACS's drift tolerance (`precision='mixed'`, `buffer_tolerance`, every 40, prune every 10;
# anchors.sh's ar_terrace_mixed_pruned); LAMMPS runs anchors.sh's argon input on the same state
# (scripts/bench/argon_anchors.py: Berendsen, skin 1 A checked every step; `replicate` tiles it).
# Rounds alternate the rank counts and decks; efficiency is the one-rank loop time over the P-rank
# loop time of the same round.
#
# Usage: scripts/bench/argon_weak.sh [RANKS [OUTDIR]]   RANKS default 1,2,4,8,16; OUTDIR a temp dir
# Environment: TERRACE (binary, default build/terrace), MPIRUN (mpirun), MPI_FLAGS (default: a rank
#   per core, bound), PS (simulated ps per run, default 200 = 20,000 steps), ROUNDS (2), DECKS
#   ("default mixed lammps"), LMP (LAMMPS binary, default lmp), BASELINE (a second Terrace binary: each
#   Terrace deck then also runs with it just before above one rank, as deck "NAME-base", for a change's
#   effect in the same rounds).
# Prints a row per run and then scripts/bench/argon_weak_report.py's table: per deck and rank count
# the median loop time, the efficiency (median and range over the rounds) and the slowest rank's
# Comm, Pair and Neigh seconds. Raw rows: OUTDIR/argon_weak.csv; each run's files in
# OUTDIR/DECK_npP_rR/; argon_weak_report.py OUTDIR --figure F.png draws them.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }
ranks="${1:-1,2,4,8,16}"; out="${2:-$(mktemp -d)}"; mkdir -p "$out"; out="$(cd "$out" && pwd)"
terrace="$(realpath "${TERRACE:-$repo/build/terrace}")"; mpirun="${MPIRUN:-mpirun}"
ps="${PS:-200}"; rounds="${ROUNDS:-2}"; decks="${DECKS:-default mixed lammps}"; lmp="${LMP:-lmp}"
[[ "$ps" =~ ^[1-9][0-9]*$ && "$rounds" =~ ^[1-9][0-9]*$ ]] || { echo "argon_weak.sh: PS and ROUNDS must be positive integers" >&2; exit 2; }
export OMP_NUM_THREADS=1 OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
# shellcheck source=ranks_lib.sh
source "$here/ranks_lib.sh"; ranks_setup "$ranks"
[[ -x "$terrace" ]] || { echo "argon_weak.sh: no Terrace binary at $terrace (build it: bash scripts/build.sh)" >&2; exit 1; }
baseline=""
if [[ -n "${BASELINE:-}" ]]; then
    baseline="$(realpath "$BASELINE")"
    [[ -x "$baseline" ]] || { echo "argon_weak.sh: BASELINE $BASELINE is not an executable" >&2; exit 1; }
    all=""; for d in $decks; do [[ $d == lammps ]] || all+=" $d-base"; all+=" $d"; done; decks="${all# }"
fi

echo "Weak scaling of the 100 ns argon job: 864 atoms per rank, ranks $ranks, $ps ps per run ($((ps * 100)) steps), $rounds rounds"
echo "machine : $(lscpu | sed -n 's/^Model name: *//p' | head -1); $ncores logical CPUs, $phys physical cores"
echo "date    : $(date -u '+%Y-%m-%d %H:%M:%S UTC')"
echo "commit  : ${BUNDLE_COMMIT:-$(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)}"
echo "terrace : $terrace${baseline:+ (decks NAME-base: $baseline)}"
echo "mpirun  : $("$mpirun" --version 2>&1 | head -1); flags: $MPI_FLAGS"
echo

# The liquid: input/argon_nvt.nml (50 ps from the lattice, Langevin) on one rank.
cd "$out"
cp "$repo/input/argon_nvt.nml" .
"$terrace" argon_nvt.nml > argon_nvt.log 2>&1 || { echo "argon_weak.sh: input/argon_nvt.nml failed" >&2; tail argon_nvt.log >&2; exit 1; }
box="$(sed -n "s/.*box_hi=\([0-9.]*\),.*/\1/p" "$repo/input/argon_nvt_100ns.nml" | head -1)"
if [[ " $decks " == *" lammps "* ]]; then   # LAMMPS's input and data for the 864 atoms, a frame every 10 ps
    mkdir -p lmp; (cd lmp && python3 "$here/argon_anchors.py" ../argon_nvt_eq.atoms "$box" $((ps * 100)) 1000 94.4 1.0)
fi
tol_ev="$(python3 -c "print('%.6g' % (0.005 / 96.48533212331))")"   # GROMACS's default drift tolerance in eV/ps

deck() {  # DECK NX NY NZ P -> the job's deck on the tiled liquid, run for $ps ps
    local d=$1 hx hy hz
    hx=$(python3 -c "print(repr($2 * $box))"); hy=$(python3 -c "print(repr($3 * $box))"); hz=$(python3 -c "print(repr($4 * $box))")
    sed -E -e "s/run_time=100000.0/run_time=$ps.0/" -e "s#atoms_file='argon_nvt_eq.atoms'#atoms_file='../liquid_np$5.atoms'#" \
           -e "s/box_hi=[0-9.]*,[0-9.]*,[0-9.]*,/box_hi=$hx,$hy,$hz,/" "$repo/input/argon_nvt_100ns.nml" > job.nml
    if [[ $d == mixed ]]; then
        sed -E -e "s#shift=.true. /#shift=.true., precision='mixed' /#" \
               -e "s#^&neighbor .*/#\&neighbor buffer_tolerance=$tol_ev, every=40, prune_every=10 /#" job.nml > job.tmp
        mv job.tmp job.nml
        grep -q "precision='mixed'" job.nml && grep -q "^&neighbor buffer_tolerance" job.nml \
            || { echo "argon_weak.sh: could not edit the mixed deck" >&2; exit 1; }
    fi
    grep -q "run_time=$ps.0" job.nml && grep -q "box_hi=$hx,$hy,$hz," job.nml && grep -q "liquid_np$5.atoms" job.nml \
        || { echo "argon_weak.sh: could not edit the job's deck" >&2; exit 1; }
}

csv="$out/argon_weak.csv"
echo "deck,round,ranks,atoms,loop_s,wall_s,comm_max_s,pair_max_s,neigh_max_s,builds" > "$csv"
for r in $(seq 1 "$rounds"); do
    for p in "${plist[@]}"; do
        read -r nx ny nz <<< "$(weak_factors "$p")"
        [[ -f "$out/liquid_np$p.atoms" ]] || awk -v nx="$nx" -v ny="$ny" -v nz="$nz" -v L="$box" '
            /^[ \t]*#/ || NF == 0 { next } { line[++n] = $0 }
            END { for (i = 0; i < nx; i++) for (j = 0; j < ny; j++) for (k = 0; k < nz; k++) for (m = 1; m <= n; m++) {
                    split(line[m], f); printf "%s %.10f %.10f %.10f", f[1], f[2] + i * L, f[3] + j * L, f[4] + k * L
                    for (q = 5; q <= 7; q++) printf " %s", f[q]; printf "\n" } }' "$out/argon_nvt_eq.atoms" > "$out/liquid_np$p.atoms"
        for d in $decks; do
            [[ $d == *-base && $p == 1 ]] && continue   # (one rank makes no MPI call)
            w="$out/${d}_np${p}_r$r"; rm -rf "$w"; mkdir -p "$w"; cd "$w"
            natoms=$(wc -l < "$out/liquid_np$p.atoms")
            t0=$(date +%s.%N)
            if [[ $d == lammps ]]; then
                sed -e "s/^read_data argon.data/read_data ..\/lmp\/argon.data\nreplicate $nx $ny $nz/" "$out/lmp/argon.in" > in.lmp
                grep -q "^replicate $nx $ny $nz" in.lmp || { echo "argon_weak.sh: could not edit LAMMPS's input" >&2; exit 1; }
                # shellcheck disable=SC2086
                if ! "$mpirun" $MPI_FLAGS -np "$p" "$lmp" -in in.lmp -log lammps.log -screen none > lammps.out 2>&1; then
                    echo "FAILED: lammps np $p round $r (log $w/lammps.log):"; tail -5 lammps.log; cd "$out"; continue; fi
                wall=$(python3 -c "print('%.3f' % ($(date +%s.%N) - $t0))")
                loop=$(sed -n 's/^Loop time of \([0-9.eE+-]*\) on.*/\1/p' lammps.log | tail -1)
                # the MPI task timing breakdown: the largest of Comm, Pair, Neigh over the ranks
                read -r comm pair neigh <<< "$(awk '/^Pair  *\|/{p=$7} /^Neigh  *\|/{n=$7} /^Comm  *\|/{c=$7} END{print c+0, p+0, n+0}' lammps.log)"
                builds=$(sed -n 's/^Neighbor list builds = *\([0-9]*\).*/\1/p' lammps.log | tail -1)
            else
                bin="$terrace"; [[ $d == *-base ]] && bin="$baseline"
                deck "${d%-base}" "$nx" "$ny" "$nz" "$p"
                # shellcheck disable=SC2086
                if ! "$mpirun" $MPI_FLAGS -np "$p" "$bin" job.nml > job.log 2>&1; then
                    echo "FAILED: $d np $p round $r (log $w/job.log):"; tail -5 job.log; cd "$out"; continue; fi
                wall=$(python3 -c "print('%.3f' % ($(date +%s.%N) - $t0))")
                s=job.summary.json
                loop=$(figure $s timing/loop_time_s); comm=$(figure $s timing/phases/Comm/max_s)
                pair=$(figure $s timing/phases/Pair/max_s); neigh=$(figure $s timing/phases/Neigh/max_s)
                builds=$(figure $s neighbor/builds 2> /dev/null || echo "")
            fi
            echo "$d,$r,$p,$natoms,$loop,$wall,$comm,$pair,$neigh,$builds" >> "$csv"
            printf '  round %d  %-7s np %2d  %6d atoms  loop %8.3f s  wall %8.3f s  Comm %7.3f  Pair %7.3f  Neigh %7.3f  builds %s\n' \
                "$r" "$d" "$p" "$natoms" "$loop" "$wall" "$comm" "$pair" "$neigh" "$builds"
            rm -f argon_nvt_100ns.h5 argon_nvt_100ns.ckpt.h5 argon_nvt_100ns.topology.data argon.lammpstrj argon.restart   # outputs: size, not data
            cd "$out"
        done
    done
done

rm -f "$out"/liquid_np*.atoms
echo
python3 "$here/argon_weak_report.py" "$out"
