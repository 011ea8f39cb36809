#!/usr/bin/env bash
# Terrace against its CPU anchors on one rank, one thread. Parts (PARTS, default all):
#   lj     LAMMPS's LJ benchmark scene (scripts/bench/in.lj_bench, input/lj_bench.nml): 32,000 atoms,
#          fcc rho* = 0.8442, T* = 1.44, rc 2.5 sigma, skin 0.3 sigma, NVE, dt 0.005 tau. Runs Terrace
#          (velocity Verlet, double; and with &potential precision = 'mixed', the mixed-precision
#          kernel over the list that list = 'auto' chooses (the atom list where the build has AVX-512,
#          else the cluster-pair list), as terrace_mixed; the same kernel over the atom list
#          (list = 'cells') as terrace_mixed_cells; with skin 0.5 (the cluster list's best on the exact
#          schedule, scripts/bench/cluster_kernel.sh) as terrace_mixed_s05; and with
#          &neighbor every = 20, check = .false., the anchors' own list schedule, as terrace_every20
#          (double) and terrace_mixed_every20 (mixed); and the mixed kernel ('auto') every
#          20 steps with the skin from &neighbor buffer_tolerance = GROMACS's default drift tolerance,
#          0.005 kJ/mol/ps per atom in LJ units, as terrace_mixed_tol), LAMMPS plain and with -sf opt,
#          GROMACS mixed (gmx mdrun) and double (gmx_d mdrun) on the same lattice in argon units (sigma
#          0.3405 nm, eps/k_B 119.8 K, m 39.948 u: rc 0.85125 nm, rlist 0.9534 nm, dt 0.010782 ps,
#          velocities at 172.5 K), and GROMACS mixed with its own buffer at its default tolerance
#          (verlet-buffer-tolerance = 0.005, nstlist 20; gromacs_mix_tol: the pair of terrace_mixed_tol).
#   eam    LAMMPS's in.eam scene (scripts/bench/in.eam_bench, Cu_u3.eam, 32,000 atoms, 1600 K, skin
#          1 A): Terrace against LAMMPS plain and -sf opt.
#   types  EAM cost per pair of the multi-type paths against the one-type path: fcc Cu with Cu_u3.eam
#          (eam, funcfl), a random 50/50 Cu-Ni alloy with CuNi.eam.alloy (eam/alloy), the same lattice
#          all Cu with CuNi.eam.alloy (setfl path, one element), the same all-Cu lattice with both
#          elements declared (cu_two_types: the multi-type path on a single type, which separates that
#          path's own cost from the random mixture's), the dilute alloy (cuni_dilute: 5 % Ni at
#          random), bcc Fe with Fe_mm.eam.fs (eam/fs) and
#          fcc Cu with Cu_mishin1.eam.alloy (one element, but 10,001 table knots like Fe_mm against 500);
#          32,000 atoms (Fe 31,250), 1600 K start, skin 1 A, Terrace and LAMMPS. Cost per pair = the
#          "Pair" phase time / (steps x pairs within rc + skin), the pair count from LAMMPS's neighbour
#          list of the same scene ("Total # of neighbors", half list, start and end averaged); LAMMPS
#          runs each scene once (first round), Terrace every round.
#   ljtypes LJ cost per pair of the multi-type path against the one-type path: the LJ scene's lattice
#          (32,000 atoms, rc 2.5, skin 0.3) with one type, with two and with three identical types (at
#          random: the same physics, so the same per-pair work), and the Kob-Andersen mixture (80:20, rho* 1.2,
#          eps/sigma AB 1.5/0.8, BB 0.5/0.88, rc 2.5 sigma_ab), velocities from LAMMPS's data file; per
#          pair as for types (pairs within rc + skin from LAMMPS's list).
#   es     energy stepping: mean cost of one event in Verlet steps (scripts/bench/es_cost.py on the
#          864-atom liquid, the 32,000-atom LJ liquid and the seven-atom cluster).
#   cluster the talk's seven-atom 2-D argon cluster with energy stepping on the all-pairs path
#          (input/argon_frozen_2d.nml: 100 ns, about 1.6 million events, a trajectory frame every
#          10 ps, 10,001 frames; CLUSTER_NS sets a shorter run): loop time, time per event, the phases
#          and the cost of a frame (the Output phase over the frames). CLUSTER_BASELINE=BINARY runs
#          that build too, alternating, with the ratio of the loop times.
#   argon  a slice of the 100 ns argon job (input/argon_nvt_100ns.nml: Rahman's liquid, 864 atoms,
#          shifted LJ at 2.5 sigma, CSVR at 94.4 K, 10 fs, thermo and a frame of x and v every 10 ps, a
#          checkpoint every 1 ns), ARGON_PS ps (default 1000: 100,000 steps) from the liquid that
#          input/argon_nvt.nml leaves: Terrace's deck as it is (ar_terrace: double, exact list), the
#          mixed kernel with &neighbor buffer_tolerance = GROMACS's default 0.005 kJ/mol/ps per atom
#          every 10 steps (ar_terrace_mixed_tol) and every 40 (ar_terrace_mixed_tol40), the double kernel
#          at the same tolerance with the list built every 40 steps and the force pass's list pruned from
#          it every 10 (ar_terrace_tol_pruned: &neighbor prune_every = 10), the same with the mixed kernel
#          over the pruned atom list (ar_terrace_mixed_pruned), GROMACS mixed
#          and double at its defaults (v-rescale, its own buffer and nstlist) and LAMMPS (Berendsen:
#          this LAMMPS has no temp/csvr) on the same state (scripts/bench/argon_anchors.py writes
#          their inputs); loop and whole-process wall times, ratios round by round.
# Every timed code runs once per round, in the same order, REPEAT rounds (alternating); the script
# prints the best and the median loop time of each, the time per atom-step and the ratios
# anchor/Terrace (> 1: Terrace is faster). Loop times are each code's own: LAMMPS "Loop time of",
# Terrace "Loop time:", GROMACS md.log "Time: ... wall t" (the MD loop; set-up and grompp excluded);
# whole-process wall times are GNU time's.
#
# Differences of the GROMACS run from the other two (as close as GROMACS allows):
#   - leap-frog (integrator = md), not velocity Verlet: the same one force evaluation per step;
#   - its cluster-pair list (nbnxm, 4x4 / 4x2 clusters) with rlist = rc + skin, rebuilt every 20
#     steps (verlet-buffer-tolerance = -1, so no automatic buffer and no dynamic pruning); LAMMPS's
#     bench input rebuilds every 20 steps without a check, Terrace whenever an atom has moved skin/2;
#   - vdw-modifier = Potential-shift (the energy shifted at rc; forces identical to the plain cutoff
#     Terrace and LAMMPS use here); zero charges with coulombtype = Cut-off (the LJ-only kernels);
#   - velocities from GROMACS's generator at the same temperature (a different random draw);
#   - energies every 100 steps like the thermo output of the other two, no trajectory output.
#
# Usage: scripts/bench/anchors.sh [NSTEPS_LJ [NSTEPS_EAM [TERRACE_BINARY]]]   (defaults 1000 200, $TERRACE or build/terrace)
# Environment: REPEAT (rounds, default 3), PARTS (comma list, default lj,eam,types,ljtypes,es,argon,cluster), INSTALL=0 to
# skip installing missing Debian packages (lammps, lammps-data, gromacs, time; as root with apt-get,
# otherwise the command is printed and the missing anchor skipped), ES_REPEAT (default 1), KEEP=1,
# GNU_TIME (GNU time's binary, default /usr/bin/time) and LAMMPS_POTENTIALS (the EAM files' folder, default
# /usr/share/lammps/potentials): scripts/bench/bundle.sh run sets both to the bundle's.
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
# Terrace's figures come from its run summaries (scripts/terrace_tools)
export PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}"
figure() { /usr/bin/python3 -m terrace_tools.summary get "$@"; }
phases() { /usr/bin/python3 -m terrace_tools.summary phases "$1.best.summary.json" | sed 's/^/    /'; }   # LABEL's best run
nlj="${1:-1000}"; neam="${2:-200}"; terrace="$(realpath "${3:-${TERRACE:-$repo/build/terrace}}")"
repeat="${REPEAT:-3}"; parts=",${PARTS:-lj,eam,types,ljtypes,es,argon,cluster},"
for v in "$nlj" "$neam" "$repeat"; do
    [[ "$v" =~ ^[1-9][0-9]*$ ]] || { echo "usage: $0 [NSTEPS_LJ [NSTEPS_EAM [TERRACE]]] (positive integers; REPEAT too)" >&2; exit 2; }
done
[[ -x "$terrace" ]] || { echo "anchors: Terrace binary '$terrace' not found (bash scripts/build.sh)" >&2; exit 2; }
pot="${LAMMPS_POTENTIALS:-/usr/share/lammps/potentials}"   # (bundle.sh run: the bundle's)
export OMP_NUM_THREADS=1 GMX_MAXBACKUP=-1

# ---- install what is missing ------------------------------------------------------------------
need=()
command -v lmp > /dev/null || need+=(lammps)
[[ -r $pot/Cu_u3.eam ]] || need+=(lammps-data)
[[ -x "${GNU_TIME:-/usr/bin/time}" ]] || need+=(time)
if [[ "$parts" == *,lj,* || "$parts" == *,argon,* ]]; then
    { command -v gmx > /dev/null && command -v gmx_d > /dev/null; } || need+=(gromacs)
fi
if [[ ${#need[@]} -gt 0 && "${INSTALL:-1}" != 0 ]]; then
    if [[ $(id -u) -eq 0 ]]; then
        echo "anchors: installing ${need[*]} (apt-get)"
        DEBIAN_FRONTEND=noninteractive apt-get update -qq
        DEBIAN_FRONTEND=noninteractive apt-get install -y -qq --no-install-recommends "${need[@]}" > /tmp/anchors-apt.log 2>&1 \
            || { echo "anchors: apt-get failed, see /tmp/anchors-apt.log" >&2; exit 1; }
    else
        echo "anchors: missing ${need[*]}; as root: apt-get install -y ${need[*]} (the anchors without their program are skipped)" >&2
    fi
fi
# every run, Terrace's too, is timed by GNU time: without it there is nothing to measure
[[ -x "${GNU_TIME:-/usr/bin/time}" ]] || { echo "anchors: GNU time (${GNU_TIME:-/usr/bin/time}) times every run and is missing: as root, apt-get install -y time (or set GNU_TIME)" >&2; exit 2; }
have() { command -v "$1" > /dev/null; }

work="$(mktemp -d "${TMPDIR:-/tmp}/anchors.XXXXXX")"
if [[ "${KEEP:-0}" != 1 ]]; then trap 'rm -rf "$work"' EXIT; fi
cd "$work"
cp "$terrace" ./terrace     # a private copy: a rebuild meanwhile must not mix versions
echo "Terrace against its CPU anchors, 1 rank, 1 thread, $repeat alternating rounds"
echo "machine : $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1) ($(env -u OMP_NUM_THREADS nproc) cores visible; flags:$(grep -o -w -E 'avx2|fma|avx512f' /proc/cpuinfo | sort -u | tr '\n' ' '))"
echo "date    : $(date -u '+%Y-%m-%d %H:%M UTC')"
echo "commit  : ${BUNDLE_COMMIT:-$(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)$(git -C "$repo" status --porcelain --untracked-files=no 2>/dev/null | grep -q . && echo ' (+ uncommitted changes)')}"
echo "load    : $(cut -d' ' -f1-3 /proc/loadavg) (load average at start)"
echo "terrace : $terrace"
echo "compiler: $(gfortran --version 2> /dev/null | head -1 || echo "(no gfortran here: a binary built elsewhere)")"
if have lmp; then echo "LAMMPS  : $(lmp -h | sed -n 's/^Large-scale Atomic.* - \(.* 20[0-9][0-9].*\)$/\1/p' | head -1)"; fi
for g in gmx gmx_d; do
    if have $g; then echo "$(printf '%-8s' $g): $($g --version 2>&1 | sed -n 's/^GROMACS version: *//p'), $($g --version 2>&1 | sed -n 's/^Precision: *//p') precision, SIMD $($g --version 2>&1 | sed -n 's/^SIMD instructions: *//p')"; fi
done
echo

# ---- timing --------------------------------------------------------------------------------------
# run LABEL KIND LOG cmd...: runs cmd in $work, appends "LABEL loop user pair wall" to runs.txt, where
# loop is the code's own loop time, user the process's user CPU time, pair its pair-force time
# (LAMMPS and Terrace; 0 if none) and wall the whole process's wall time (GNU time).
: > runs.txt
loop_of() {   # KIND LOG [SUMMARY]
    case $1 in
        lammps)  sed -n 's/^Loop time of \([0-9.eE+-]*\) on .*/\1/p' "$2" | tail -1 ;;
        terrace) figure "$3" timing/loop_time_s ;;
        gromacs) awk '/^ *Time: /{print $3}' "$2" | tail -1 ;;
    esac
}
pair_of() {
    case $1 in
        lammps)  awk -F'|' '/^Pair /{gsub(/ /,"",$3); print $3}' "$2" | tail -1 ;;
        terrace) figure "$3" timing/phases/Pair/avg_s ;;
        *)       echo 0 ;;
    esac
}
run() {
    local label=$1 kind=$2 log=$3; shift 3
    if ! "${GNU_TIME:-/usr/bin/time}" -f '%U %e' -o user.txt "$@" > "$label.out" 2>&1; then
        echo "anchors: $label failed: $*" >&2; tail -n 15 "$label.out" >&2; [[ -f "$log" ]] && tail -n 15 "$log" >&2; exit 1
    fi
    local sum=""; [[ $kind == terrace ]] && { sum="${*: -1}"; sum="${sum%.nml}.summary.json"; }   # the deck's
    local t; t="$(loop_of "$kind" "$log" "$sum")"
    [[ -n "$t" ]] || { echo "anchors: no loop time for $label in $log" >&2; exit 1; }
    local user wall; read -r user wall < <(tail -1 user.txt)
    echo "$label $t $user $(pair_of "$kind" "$log" "$sum") $wall" >> runs.txt
    if [[ ! -f $label.best ]] || awk -v a="$t" -v b="$(cat "$label.best")" 'BEGIN { exit !(a < b) }'; then
        echo "$t" > "$label.best"; cp "$log" "$label.best.log"
        [[ -z $sum ]] || cp "$sum" "$label.best.summary.json"
    fi
}
# launch LABEL: one timed run of that code on its scene (LJ: lj.nml, in.lj_bench, gmx*.tpr; EAM: in.eam)
gargs=(mdrun -ntmpi 1 -ntomp 1 -nb cpu -pin off -noconfout -g md.log -e ener.edr -o traj.trr -cpo state.cpt)
launch() {
    case $1 in
        terrace)        run terrace terrace terrace.out ./terrace lj.nml ;;
        terrace_mixed)  run terrace_mixed terrace terrace_mixed.out ./terrace lj_mixed.nml ;;
        terrace_every20) run terrace_every20 terrace terrace_every20.out ./terrace lj_every20.nml ;;
        terrace_mixed_cells) run terrace_mixed_cells terrace terrace_mixed_cells.out ./terrace lj_mixed_cells.nml ;;
        terrace_mixed_s05) run terrace_mixed_s05 terrace terrace_mixed_s05.out ./terrace lj_mixed_s05.nml ;;
        terrace_mixed_every20) run terrace_mixed_every20 terrace terrace_mixed_every20.out ./terrace lj_mixed_every20.nml ;;
        terrace_mixed_tol) run terrace_mixed_tol terrace terrace_mixed_tol.out ./terrace lj_mixed_tol.nml ;;
        lammps)         run lammps lammps lammps.log lmp -screen none -log lammps.log -var nsteps "$nlj" -in "$here/in.lj_bench" ;;
        lammps_opt)     run lammps_opt lammps lammps.log lmp -sf opt -screen none -log lammps.log -var nsteps "$nlj" -in "$here/in.lj_bench" ;;
        gromacs_mix)    run gromacs_mix gromacs md.log gmx "${gargs[@]}" -s gmx.tpr ;;
        gromacs_dbl)    run gromacs_dbl gromacs md.log gmx_d "${gargs[@]}" -s gmx_d.tpr ;;
        gromacs_mix_tol) run gromacs_mix_tol gromacs md.log gmx "${gargs[@]}" -s gmx_tol.tpr ;;
        eam_terrace)    run eam_terrace terrace eam_terrace.out ./terrace eam.nml ;;
        eam_lammps)     run eam_lammps lammps lammps.log lmp -screen none -log lammps.log -var nsteps "$neam" -var potdir "$pot" -in "$here/in.eam_bench" ;;
        eam_lammps_opt) run eam_lammps_opt lammps lammps.log lmp -sf opt -screen none -log lammps.log -var nsteps "$neam" -var potdir "$pot" -in "$here/in.eam_bench" ;;
        ar_terrace|ar_terrace_mixed_tol|ar_terrace_mixed_tol40|ar_terrace_tol_pruned|ar_terrace_mixed_pruned)
                        rm -f argon_nvt_100ns.csv argon_nvt_100ns.h5 argon_nvt_100ns.ckpt.h5   # the decks' outputs, fresh
                        run $1 terrace $1.out ./terrace $1.nml ;;
        ar_gromacs_mix) run ar_gromacs_mix gromacs md.log gmx "${gargs[@]}" -s argon_gmx.tpr ;;
        ar_gromacs_dbl) run ar_gromacs_dbl gromacs md.log gmx_d "${gargs[@]}" -s argon_gmx_d.tpr ;;
        ar_lammps)      run ar_lammps lammps lammps.log lmp -screen none -log lammps.log -in argon.in ;;
    esac
}
# rounds LABEL...: REPEAT rounds, each code once per round in the given order (alternating)
rounds() {
    local rep l
    for ((rep = 1; rep <= repeat; rep++)); do
        for l in "$@"; do launch "$l"; done
    done
}
# summary NATOMS NSTEPS REF LABEL...: best and median loop time, ns per atom-step, ratios to REF
summary() {
    python3 - "$@" <<'PY'
import sys, statistics as st
natoms, nsteps, ref, labels = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3], sys.argv[4:]
runs = {}
for line in open('runs.txt'):
    f = line.split()
    runs.setdefault(f[0], []).append([float(x) for x in f[1:]])
rows = [(l, runs[l]) for l in labels if l in runs]
best = {l: min(r[0] for r in rs) for l, rs in rows}
med = {l: st.median([r[0] for r in rs]) for l, rs in rows}
print('%-14s %4s %8s %8s %9s %8s %9s %9s  %s' % ('code', 'runs', 'best s', 'median s', 'ns/at-st', 'user s',
                                                  'ns/at-st', 'vs Terr.', 'all loop times (s)'))
print('%-14s %4s %8s %8s %9s %8s %9s %9s' % ('', '', 'loop', 'loop', 'best loop', 'median', 'med user',
                                             'best/med'))
for l, rs in rows:
    ratio = ('%4.2f/%4.2f' % (best[l] / best[ref], med[l] / med[ref])) if ref in best and l != ref else ''
    u = st.median([r[1] for r in rs])
    print('%-14s %4d %8.3f %8.3f %9.1f %8.2f %9.1f %9s  %s' % (l, len(rs), best[l], med[l],
          1e9 * best[l] / (natoms * nsteps), u, 1e9 * u / (natoms * nsteps), ratio,
          ' '.join('%.2f' % r[0] for r in rs)))
if ref in best:
    print("ratios anchor/Terrace ('vs Terr.'; > 1: Terrace is faster): loop times best, median; user CPU "
          "time of the whole process, median (includes set-up)")
    user = {l: st.median([r[1] for r in rs]) for l, rs in rows}
    for l, _ in rows:
        if l != ref:
            print('  %-14s %.3f (best)  %.3f (median)  %.3f (user)' % (l, best[l] / best[ref], med[l] / med[ref],
                                                                    user[l] / user[ref]))
    # paired: round by round (each round runs every code once, one after the other, so a load that
    # changes slowly weighs on both runs of a pair); their median and range
    n = min(len(rs) for _, rs in rows)
    if n > 1:
        print('paired ratios anchor/Terrace, round by round (loop times of the same round): median [lowest, highest] of %d'
              % n)
        for l, rs in rows:
            if l != ref:
                q = sorted(rs[k][0] / runs[ref][k][0] for k in range(n))
                print('  %-14s %.3f  [%.3f, %.3f]' % (l, st.median(q), q[0], q[-1]))
PY
}

# ---- LJ scene ------------------------------------------------------------------------------------
if [[ "$parts" == *,lj,* ]]; then
    sed -E "s/n_steps=[0-9]+/n_steps=$nlj/" "$repo/input/lj_bench.nml" > lj.nml
    sed -E "s#shift=.false. /#shift=.false., precision='mixed' /#" lj.nml > lj_mixed.nml
    grep -q "precision='mixed'" lj_mixed.nml || { echo "anchors: could not set precision='mixed' in lj_mixed.nml" >&2; exit 1; }
    sed -E "s#skin=0.3 /#skin=0.3, every=20, check=.false. /#" lj.nml > lj_every20.nml
    grep -q "every=20" lj_every20.nml || { echo "anchors: could not set every=20 in lj_every20.nml" >&2; exit 1; }
    sed -E "s#skin=0.3 /#skin=0.3, list='cells' /#" lj_mixed.nml > lj_mixed_cells.nml
    sed -E "s#skin=0.3 /#skin=0.5 /#" lj_mixed.nml > lj_mixed_s05.nml
    sed -E "s#skin=0.3 /#skin=0.3, every=20, check=.false. /#" lj_mixed.nml > lj_mixed_every20.nml
    # GROMACS's default drift tolerance, 0.005 kJ/mol/ps per atom, in eps/tau for argon (eps/k_B 119.8 K,
    # sigma 0.3405 nm, m 39.948 u: tau = sigma sqrt(m/eps) ps)
    tol_lj="$(python3 -c "kb=0.00831446261815324; e=119.8*kb; print('%.6g' % (0.005*0.3405*(39.948/e)**0.5/e))")"
    sed -E "s#skin=0.3 /#every=20, buffer_tolerance=$tol_lj /#" lj_mixed.nml > lj_mixed_tol.nml
    for f in lj_mixed_cells lj_mixed_s05 lj_mixed_every20 lj_mixed_tol; do
        cmp -s $f.nml lj_mixed.nml && { echo "anchors: could not edit the &neighbor line for $f.nml" >&2; exit 1; }
    done
    labels=(terrace terrace_mixed terrace_every20 terrace_mixed_cells terrace_mixed_s05 terrace_mixed_every20 terrace_mixed_tol)
    have lmp && labels+=(lammps lammps_opt)
    gro=0; have gmx && gro=1; have gmx_d && gro=1
    if [[ $gro == 1 ]]; then
        # the LAMMPS lattice (fcc, 4-atom basis, 20^3 cells at rho* 0.8442) in argon units
        python3 "$here/lj_gromacs.py" "$nlj"
        for g in gmx gmx_d; do
            have $g || continue
            $g grompp -f lj.mdp -c lj.gro -p lj.top -o $g.tpr -po $g.mdout.mdp -maxwarn 10 > $g.grompp.log 2>&1 \
                || { echo "anchors: $g grompp failed:" >&2; tail -30 $g.grompp.log >&2; exit 1; }
            if [[ $g == gmx ]]; then labels+=(gromacs_mix); else labels+=(gromacs_dbl); fi
        done
        if have gmx; then
            gmx grompp -f lj_tol.mdp -c lj.gro -p lj.top -o gmx_tol.tpr -po gmx_tol.mdout.mdp -maxwarn 10 > gmx_tol.grompp.log 2>&1 \
                || { echo "anchors: gmx grompp (lj_tol.mdp) failed:" >&2; tail -30 gmx_tol.grompp.log >&2; exit 1; }
            labels+=(gromacs_mix_tol)
        fi
        glog=$(ls gmx*.grompp.log | head -1)
        if grep -q -E '^(WARNING|NOTE)' "$glog"; then
            echo "grompp notes and warnings (the LJ scene in GROMACS; -maxwarn 10):"
            grep -h -A4 -E '^(WARNING|NOTE)' "$glog" | grep -v -E '^(--)?$' | sed 's/^/    /' | head -20
        fi
    fi
    echo "== LJ scene: 32,000 atoms, $nlj steps; codes: ${labels[*]}"
    rounds "${labels[@]}"
    summary 32000 "$nlj" terrace "${labels[@]}"
    echo "The same against Terrace's mixed-precision kernel (terrace_mixed):"
    summary 32000 "$nlj" terrace_mixed "${labels[@]}" | sed -n '/^ratios anchor/,$p'
    echo
    echo "Terrace phases (best run):"
    phases terrace
    echo "Terrace mixed-precision kernel, phases (best run):"
    phases terrace_mixed
    echo "The same against Terrace on the anchors' list schedule (terrace_every20: rebuilt every 20 steps, no check):"
    summary 32000 "$nlj" terrace_every20 "${labels[@]}" | sed -n '/^ratios anchor/,$p'
    echo "Terrace on the anchors' list schedule, phases (best run):"
    phases terrace_every20
    for v in terrace_mixed_s05 terrace_mixed_every20; do
        echo "The same against Terrace's mixed kernel ('auto'), $v:"
        summary 32000 "$nlj" $v "${labels[@]}" | sed -n '/^ratios anchor/,$p'
    done
    echo "Each code's own buffer at GROMACS's default drift tolerance (0.005 kJ/mol/ps per atom = $tol_lj eps/tau),"
    echo "every 20 steps: Terrace's mixed kernel ('auto') (terrace_mixed_tol) against the anchors:"
    summary 32000 "$nlj" terrace_mixed_tol "${labels[@]}" | sed -n '/^ratios anchor/,$p'
    echo "  skins: Terrace $(figure lj_mixed_tol.summary.json neighbor/skin) sigma;" \
         "$( [[ -f gromacs_mix_tol.best.log ]] && grep -m1 -E 'updated every .* steps, buffer' gromacs_mix_tol.best.log | sed 's/^ *//; s/^/GROMACS /')"
    echo "  measured energy drift per atom (eps/tau; GROMACS's 'Conserved energy drift' converted with eps and tau):"
    echo "    terrace_mixed (exact list)  $(figure lj_mixed.summary.json conservation/energy_drift_per_atom_time)"
    echo "    terrace_mixed_tol           $(figure lj_mixed_tol.summary.json conservation/energy_drift_per_atom_time)"
    for l in gromacs_mix gromacs_mix_tol; do
        [[ -f $l.best.log ]] || continue
        d="$(sed -n 's/^ *Conserved energy drift: *\([0-9.eE+-]*\) kJ\/mol\/ps per atom.*/\1/p' $l.best.log | tail -1)"
        [[ -n "$d" ]] && echo "    $(printf '%-27s' $l) $(python3 -c "print('%.4E' % ($d * float('$tol_lj') / 0.005))")"
    done
    echo "Terrace's mixed variants, phases (best runs):"
    for v in terrace_mixed_cells terrace_mixed_s05 terrace_mixed_every20 terrace_mixed_tol; do
        echo "  $v:"
        phases $v
    done
    echo "Energy drift per atom per tau of the exact schedule and of every 20 steps (Terrace's run summaries; the same scene and seed):"
    for d in lj lj_every20; do echo "    $d: $(figure $d.summary.json conservation/energy_drift_per_atom_time)"; done
    echo "  mixed kernel ('auto'), exact and every 20 steps:"
    for d in lj_mixed lj_mixed_every20; do echo "    $d: $(figure $d.summary.json conservation/energy_drift_per_atom_time)"; done
    /usr/bin/python3 - "$nlj" <<'PY'
import os, re, sys
from terrace_tools import summary
nsteps, natoms = int(sys.argv[1]), 32000
def read(name):
    return open(name).read() if os.path.exists(name) else None
def num(pat, text, k=1):
    m = re.findall(pat, text, re.M)
    return float(m[-1] if isinstance(m[-1], str) else m[-1][k - 1]) if m else None
pairs = None
lmp = read('lammps.best.log')
if lmp:
    pairs = num(r'^Total # of neighbors = (\d+)', lmp)
print('Where the time goes (best run of each; pairs = %s atom pairs within rc + skin, LAMMPS half list at the end):'
      % ('%.4g' % pairs if pairs else '?'))
print('  %-14s %10s %12s %10s %12s %14s' % ('code', 'force s', 'ns/pair', 'builds', 'ms/build', 'ns/atom-build'))
rows = []
for l in ('terrace', 'terrace_mixed', 'terrace_every20', 'terrace_mixed_cells', 'terrace_mixed_s05', 'terrace_mixed_every20',
          'terrace_mixed_tol'):
    if os.path.exists(l + '.best.summary.json'):
        s = summary.read(l + '.best.summary.json')
        rows.append((l, summary.get(s, 'timing/phases/Pair/avg_s'), summary.get(s, 'timing/phases/Neigh/avg_s'),
                     summary.get(s, 'neighbor/builds')))
for l in ('lammps', 'lammps_opt'):
    t = read(l + '.best.log')
    if t:
        rows.append((l, num(r'^Pair\s+\|\s*[0-9.eE+-]+\s*\|\s*([0-9.eE+-]+)', t),
                     num(r'^Neigh\s+\|\s*[0-9.eE+-]+\s*\|\s*([0-9.eE+-]+)', t), num(r'^Neighbor list builds = (\d+)', t)))
for l in ('gromacs_mix', 'gromacs_dbl', 'gromacs_mix_tol'):
    t = read(l + '.best.log')
    if t:
        ns = re.findall(r'^ Neighbor search\s+\d+\s+\d+\s+(\d+)\s+([0-9.]+)', t, re.M)
        fo = re.findall(r'^ Force\s+\d+\s+\d+\s+\d+\s+([0-9.]+)', t, re.M)
        nxn = sum(float(x) for x in re.findall(r'^ NxN LJ \[V?&?F\]\s+([0-9.]+)', t, re.M))
        rows.append((l, float(fo[-1]), float(ns[-1][1]), float(ns[-1][0]) - 1))
        print('  (%s: %.4g cluster-pair atom-pair interactions per step computed, %.2f per list pair; '
              'GROMACS counts its initial search as a build, not here)' % (l, 1e6 * nxn / nsteps, 1e6 * nxn / nsteps / pairs if pairs else float('nan')))
for l, fp, nb, b in rows:
    if fp is None:
        continue
    per_pair = 1e9 * fp / (nsteps * pairs) if pairs else float('nan')
    b = max(b or 0, 1)
    print('  %-14s %10.3f %12.3f %10d %12.2f %14.1f' % (l, fp, per_pair, b, 1e3 * nb / b, 1e9 * nb / b / natoms))
PY
    for l in gromacs_mix gromacs_dbl gromacs_mix_tol; do
        [[ -f $l.best.log ]] && echo "  $l: $(grep -m1 -E 'Using .*nonbonded short-range kernels' $l.best.log), $(grep -m1 -E 'updated every .* steps, buffer' $l.best.log | sed 's/^ *//')"
    done
    echo
fi

# ---- EAM: LAMMPS's in.eam ------------------------------------------------------------------------
if [[ "$parts" == *,eam,* ]]; then
    cat > eam.nml <<NML
&run units='metal', dimension=3, n_steps=$neam, seed=376847 /
&system lattice='fcc', lattice_constant=3.615, cells=20,20,20, periodic=.true.,.true.,.true., temperature=1600.0 /
&potential style='eam', file='$pot/Cu_u3.eam' /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=1.0 /
&output thermo_every=50, thermo_file='' /
NML
    labels=(eam_terrace); have lmp && labels+=(eam_lammps eam_lammps_opt)
    echo "== EAM scene (in.eam): 32,000 Cu atoms, Cu_u3.eam, $neam steps; both rebuild on the skin/2 check"
    rounds "${labels[@]}"
    summary 32000 "$neam" eam_terrace "${labels[@]}"
    echo "Terrace phases (best run):"
    phases eam_terrace
    echo
fi

# per_pair_rounds LIST: REPEAT rounds of Terrace on each scene of LIST (NAME.nml), in order; LAMMPS
# (NAME.in) in the first round only: its pair counts and its own per-pair costs.
per_pair_rounds() {
    local rep name style file
    for ((rep = 1; rep <= repeat; rep++)); do
        while read -r name style file; do
            run "t_$name" terrace "t_$name.out" ./terrace "$name.nml"
            if [[ $rep == 1 ]]; then
                run "l_$name" lammps lammps.log lmp -screen none -log lammps.log -in "$name.in"
            fi
        done < "$1"
    done
}
# per_pair_table NSTEPS LIST REF WORD WHAT: the per-pair table of the scenes in LIST (name style file), each
# against REF (listed first), from runs.txt (t_NAME: Terrace, every round; l_NAME: LAMMPS, once).
per_pair_table() {
    python3 - "$@" <<'PY'
import sys, re, statistics as st
nsteps, listfile, refname, refword, what = int(sys.argv[1]), sys.argv[2], sys.argv[3], sys.argv[4], sys.argv[5]
runs = {}
for line in open('runs.txt'):
    f = line.split()
    runs.setdefault(f[0], []).append([float(x) for x in f[1:]])
print('%-11s %-9s %-20s %7s %9s %11s %11s %9s %9s %11s %9s' % ('scene', 'style', 'file', 'atoms', 'pairs/at',
      'T pair s', 'T ns/pair', 'T vs ' + refword, 'T med', 'L ns/pair', 'L vs ' + refword))
ref = None
for line in open(listfile):
    name, style, fname = line.split()
    log = open('l_%s.best.log' % name).read()
    nb = [int(x) for x in re.findall(r'^Total # of neighbors = (\d+)', log, re.M)]
    natoms = int(re.findall(r'^Loop time of .* with (\d+) atoms', log, re.M)[-1])
    pairs = 0.5 * (nb[-2] + nb[-1])          # start (run 0) and end of the timed run
    tp = min(r[2] for r in runs['t_' + name]); tm = st.median(r[2] for r in runs['t_' + name])
    lp = min(r[2] for r in runs['l_' + name])
    tns, tms, lns = (1e9 * t / (nsteps * pairs) for t in (tp, tm, lp))
    if name == refname:
        ref = (tns, tms, lns)
    print('%-11s %-9s %-20s %7d %9.2f %11.3f %11.3f %9.2f %9.2f %11.3f %9.2f' % (name, style, fname, natoms,
          pairs / natoms, tp, tns, tns / ref[0], tms / ref[1], lns, lns / ref[2]))
print('T = Terrace ("Pair" phase time: the best of the rounds; vs %s from the best and from the median), L = LAMMPS (one '
      'run, its "Pair" time), per step and per pair within rc + skin (LAMMPS half list); vs %s = per-pair cost / that of '
      '%s (goal for Terrace\'s %s: <= 1.20).' % (refword, refword, refname, what))
PY
}

# ---- EAM: cost per pair, one type against eam/alloy and eam/fs --------------------------------
if [[ "$parts" == *,types,* ]] && have lmp; then
    # name lattice a cells style file elements(LAMMPS order) data? (0: lattice deck; 1: a data file with
    # half the atoms of type 2 at random; 2: a data file with two types, every atom of type 1; 3: as 1
    # with 5 % of type 2, a dilute alloy)
    scenes=("cu_u3 fcc 3.615 20 eam Cu_u3.eam - 0"
            "cuni_alloy fcc 3.56 20 eam/alloy CuNi.eam.alloy Cu,Ni 1"
            "cu_alloy fcc 3.56 20 eam/alloy CuNi.eam.alloy Cu 0"
            "cu_two_types fcc 3.56 20 eam/alloy CuNi.eam.alloy Cu,Ni 2"
            "cuni_dilute fcc 3.56 20 eam/alloy CuNi.eam.alloy Cu,Ni 3"
            "fe_fs bcc 2.8553 25 eam/fs Fe_mm.eam.fs Fe 0"
            "cu_mishin fcc 3.615 20 eam/alloy Cu_mishin1.eam.alloy Cu 0")
    echo "== EAM cost per pair: one type (eam) against eam/alloy and eam/fs, $neam steps, 1600 K start, skin 1 A"
    : > types.txt
    for s in "${scenes[@]}"; do
        read -r name lat a n style file elems data <<< "$s"
        ntypes=1; [[ $data != 0 ]] && ntypes=2
        coeff="* * $pot/$file ${elems//,/ }"; [[ $style == eam ]] && coeff="1 1 $pot/$file"
        cat > $name.in <<LMP
variable nrun index $neam
units metal
atom_style atomic
lattice $lat $a
region box block 0 $n 0 $n 0 $n
create_box $ntypes box
create_atoms 1 box
$( [[ $data == 1 ]] && echo "set type 1 type/fraction 2 0.5 8675309" )
$( [[ $data == 3 ]] && echo "set type 1 type/fraction 2 0.05 8675309" )
pair_style $style
pair_coeff $coeff
velocity all create 1600.0 376847 loop geom
neighbor 1.0 bin
neigh_modify every 1 delay 0 check yes
fix 1 all nve
timestep 0.005
thermo 50
$( [[ $data != 0 ]] && echo "write_data $name.data nocoeff" )
run 0
run \${nrun}
LMP
        tel=""; [[ $style != eam ]] && tel=", elements=$(sed "s/\([A-Za-z]*\)/'\1'/g" <<< "$elems")"
        if [[ $data != 0 ]]; then
            sys="read_data='$name.data'"
            lmp -screen none -log $name.make.log -var nrun 0 -in $name.in > /dev/null   # writes the data file
        else
            sys="lattice='$lat', lattice_constant=$a, cells=$n,$n,$n, periodic=.true.,.true.,.true., temperature=1600.0"
        fi
        cat > $name.nml <<NML
&run units='metal', dimension=3, n_steps=$neam, seed=376847 /
&system $sys /
&potential style='$style', file='$pot/$file'$tel /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=1.0 /
&output thermo_every=50, thermo_file='' /
NML
        echo "$name $style $file" >> types.txt
    done
    per_pair_rounds types.txt
    per_pair_table "$neam" types.txt cu_u3 'Cu' 'eam/alloy, eam/fs'
    echo
fi

# ---- LJ: cost per pair, one type against mixtures -----------------------------------------------
if [[ "$parts" == *,ljtypes,* ]] && have lmp; then
    # name density type-2-fraction T (lj_three_same: then half of the type-1 atoms become type 3)
    scenes=("lj_one 0.8442 0 1.44"
            "lj_two_same 0.8442 0.5 1.44"
            "lj_three_same 0.8442 0.333333 1.44"
            "lj_ka 1.2 0.2 2.0")
    echo "== LJ cost per pair: one type against two and three (identical types; Kob-Andersen 80:20), $nlj steps, skin 0.3"
    : > ljtypes.txt
    for s in "${scenes[@]}"; do
        read -r name rho frac temp <<< "$s"
        ntypes=1; [[ $frac != 0 ]] && ntypes=2; [[ $name == lj_three_same ]] && ntypes=3
        case $name in
            lj_one)      lcoeff="pair_coeff 1 1 1.0 1.0 2.5"; tkeys="epsilon=1.0, sigma=1.0" ;;
            lj_two_same) lcoeff="pair_coeff * * 1.0 1.0 2.5"; tkeys="epsilon(1,1)=1.0, sigma(1,1)=1.0, epsilon(2,2)=1.0, sigma(2,2)=1.0" ;;
            lj_three_same) lcoeff="pair_coeff * * 1.0 1.0 2.5"
                           tkeys="epsilon(1,1)=1.0, sigma(1,1)=1.0, epsilon(2,2)=1.0, sigma(2,2)=1.0, epsilon(3,3)=1.0, sigma(3,3)=1.0" ;;
            lj_ka)       lcoeff=$'pair_coeff 1 1 1.0 1.0 2.5\npair_coeff 1 2 1.5 0.8 2.0\npair_coeff 2 2 0.5 0.88 2.2'
                         tkeys="epsilon(1,1)=1.0, sigma(1,1)=1.0, epsilon(2,2)=0.5, sigma(2,2)=0.88, epsilon(1,2)=1.5, sigma(1,2)=0.8, pair_cutoff(1,2)=2.0, pair_cutoff(2,2)=2.2" ;;
        esac
        cat > $name.in <<LMP
variable nrun index $nlj
units lj
atom_style atomic
lattice fcc $rho
region box block 0 20 0 20 0 20
create_box $ntypes box
create_atoms 1 box
$( [[ $ntypes -ge 2 ]] && echo "set type 1 type/fraction 2 $frac 8675309" )
$( [[ $ntypes == 3 ]] && echo "set type 1 type/fraction 3 0.5 5551212" )
mass * 1.0
velocity all create $temp 87287 loop geom
pair_style lj/cut 2.5
$lcoeff
neighbor 0.3 bin
neigh_modify every 1 delay 0 check yes
fix 1 all nve
timestep 0.005
thermo 100
write_data $name.data nocoeff
run 0
run \${nrun}
LMP
        lmp -screen none -log $name.make.log -var nrun 0 -in $name.in > /dev/null   # the data file, velocities included
        cat > $name.nml <<NML
&run units='lj', dimension=3, n_steps=$nlj /
&system read_data='$name.data', periodic=.true.,.true.,.true. /
&potential style='lj', $tkeys, cutoff=2.5, shift=.false. /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=100, thermo_file='' /
NML
        echo "$name lj/cut -" >> ljtypes.txt
    done
    per_pair_rounds ljtypes.txt
    per_pair_table "$nlj" ljtypes.txt lj_one 'one' 'mixtures'
    echo "Thermo at step $nlj, one type and two or three identical types (same data, velocities by position):"
    for name in lj_one lj_two_same lj_three_same; do
        printf '    %-12s Terrace pe, etotal: %s   LAMMPS pe, etotal per atom: %s\n' $name \
            "$(figure $name.summary.json thermo_last/pe) $(figure $name.summary.json thermo_last/etotal)" \
            "$(awk -v n="$nlj" '$1 == n && NF == 6 {print $3, $5; exit}' l_$name.best.log)"
    done
    echo
fi

# ---- energy stepping ------------------------------------------------------------------------------
if [[ "$parts" == *,es,* ]]; then
    echo "== energy stepping: cost of one event in Verlet steps (scripts/bench/es_cost.py)"
    python3 "$here/es_cost.py" --terrace ./terrace --scenes rahman,lj32k,cluster7 --repeat "${ES_REPEAT:-1}" \
        | sed -n '/^scene /,$p'
fi

# ---- the 100 ns argon job, a slice of it --------------------------------------------------------------
if [[ "$parts" == *,argon,* ]]; then
    ps="${ARGON_PS:-1000}"
    [[ "$ps" =~ ^[1-9][0-9]*$ ]] || { echo "anchors: ARGON_PS must be a positive integer (ps)" >&2; exit 2; }
    nar=$((ps * 100))                                     # steps of 10 fs
    echo "== Rahman's liquid argon, 864 atoms, the 100 ns job (input/argon_nvt_100ns.nml) for $ps ps = $nar steps:"
    echo "   CSVR at 94.4 K (damping 1 ps), thermo and a frame of x and v every 10 ps, a checkpoint every 1 ns"
    cp "$repo/input/argon_nvt.nml" .
    ./terrace argon_nvt.nml > argon_nvt.log 2>&1 || { echo "anchors: input/argon_nvt.nml failed" >&2; tail argon_nvt.log >&2; exit 1; }
    sed -e "s/run_time=100000.0/run_time=$ps.0/" "$repo/input/argon_nvt_100ns.nml" > ar_terrace.nml
    grep -q "run_time=$ps.0" ar_terrace.nml || { echo "anchors: could not set run_time in ar_terrace.nml" >&2; exit 1; }
    # GROMACS's default drift tolerance, 0.005 kJ/mol/ps per atom, in eV/ps
    tol_ev="$(python3 -c "print('%.6g' % (0.005 / 96.48533212331))")"
    sed -E -e "s#shift=.true. /#shift=.true., precision='mixed' /#" -e "s#^&neighbor .*/#\&neighbor buffer_tolerance=$tol_ev /#" \
        ar_terrace.nml > ar_terrace_mixed_tol.nml
    sed -E "s#buffer_tolerance=$tol_ev /#buffer_tolerance=$tol_ev, every=40 /#" ar_terrace_mixed_tol.nml > ar_terrace_mixed_tol40.nml
    for f in ar_terrace_mixed_tol ar_terrace_mixed_tol40; do
        grep -q "precision='mixed'" $f.nml && ! cmp -s $f.nml ar_terrace.nml && grep -q '^&neighbor buffer_tolerance' $f.nml \
            || { echo "anchors: could not edit $f.nml" >&2; exit 1; }
    done
    [[ $(grep -c '^&neighbor .*every=40' ar_terrace_mixed_tol40.nml) == 1 ]] || { echo "anchors: could not set every=40" >&2; exit 1; }
    sed -E "s#^&neighbor .*/#\&neighbor buffer_tolerance=$tol_ev, every=40, prune_every=10 /#" ar_terrace.nml > ar_terrace_tol_pruned.nml
    [[ $(grep -c "^&neighbor buffer_tolerance=$tol_ev, every=40, prune_every=10 /" ar_terrace_tol_pruned.nml) == 1 ]] \
        || { echo "anchors: could not edit ar_terrace_tol_pruned.nml" >&2; exit 1; }
    sed -E "s#shift=.true. /#shift=.true., precision='mixed' /#" ar_terrace_tol_pruned.nml > ar_terrace_mixed_pruned.nml
    [[ $(grep -c "^&potential .*precision='mixed' /" ar_terrace_mixed_pruned.nml) == 1 ]] \
        || { echo "anchors: could not edit ar_terrace_mixed_pruned.nml" >&2; exit 1; }
    boxl="$(sed -n "s/.*box_hi=\([0-9.]*\),.*/\1/p" ar_terrace.nml | head -1)"
    python3 "$here/argon_anchors.py" argon_nvt_eq.atoms "$boxl" "$nar" 1000 94.4 1.0
    labels=(ar_terrace ar_terrace_mixed_tol ar_terrace_mixed_tol40 ar_terrace_tol_pruned ar_terrace_mixed_pruned)
    for g in gmx gmx_d; do
        have $g || continue
        $g grompp -f argon.mdp -c argon.gro -p argon.top -o argon_$g.tpr -po argon_$g.mdout.mdp -maxwarn 10 \
            > argon_$g.grompp.log 2>&1 || { echo "anchors: $g grompp (argon) failed:" >&2; tail -30 argon_$g.grompp.log >&2; exit 1; }
        if [[ $g == gmx ]]; then labels+=(ar_gromacs_mix); else labels+=(ar_gromacs_dbl); fi
    done
    have lmp && labels+=(ar_lammps)
    echo "   codes: ${labels[*]}"
    echo "   ar_terrace: the deck as it is (double, exact list: skin 0.6 A pruned from outer_skin 2.6 A); ar_terrace_mixed_tol: precision='mixed'"
    echo "   (the list 'auto' chooses), &neighbor buffer_tolerance=$tol_ev eV/ps (GROMACS's default 0.005 kJ/mol/ps),"
    echo "   every 10 steps (the key's default); ar_terrace_mixed_tol40: the same every 40 steps; ar_terrace_tol_pruned:"
    echo "   double precision, the same tolerance, built every 40 steps, the force pass's list pruned every 10;"
    echo "   ar_terrace_mixed_pruned: the same with precision='mixed' (the mixed kernel over the pruned atom list); the mixed runs"
    echo "   read the periodic images as their owners (&neighbor images = 'auto': copied at builds and prunes only); GROMACS: leap-frog,"
    echo "   v-rescale (tau-t 1 ps), its Verlet buffer at its default tolerance, nstcalcenergy 100, energies and"
    echo "   a trr frame (x, v) every 1000 steps; LAMMPS: velocity Verlet, fix temp/berendsen (1 ps; this"
    echo "   LAMMPS has no temp/csvr), skin 1 A checked every step, thermo and a dump (x, v) every 1000 steps"
    rounds "${labels[@]}"
    /usr/bin/python3 - "$nar" "${labels[@]}" <<'PY'
import statistics as st, sys
nsteps, labels = int(sys.argv[1]), sys.argv[2:]
runs = {}
for line in open('runs.txt'):
    f = line.split()
    if f[0] in labels:
        runs.setdefault(f[0], []).append((float(f[1]), float(f[4]), float(f[2])))   # loop, wall, user
rows = [l for l in labels if l in runs]
print('%-22s %4s %9s %9s %9s %9s %9s  %s' % ('code', 'runs', 'loop best', 'loop med', 'wall med', 'user med',
                                             'us/step', 'all loop times (s)'))
for l in rows:
    rs = runs[l]
    print('%-22s %4d %9.3f %9.3f %9.3f %9.3f %9.2f  %s' % (l, len(rs), min(r[0] for r in rs),
          st.median(r[0] for r in rs), st.median(r[1] for r in rs), st.median(r[2] for r in rs),
          1e6 * st.median(r[0] for r in rs) / nsteps, ' '.join('%.2f' % r[0] for r in rs)))
n = min(len(runs[l]) for l in rows)
for ref in ('ar_terrace', 'ar_terrace_mixed_tol', 'ar_terrace_mixed_tol40', 'ar_terrace_tol_pruned', 'ar_terrace_mixed_pruned'):
    if ref not in runs:
        continue
    print('ratios code / %s, round by round (> 1: %s is faster): median [lowest, highest] of %d rounds' % (ref, ref, n))
    print('  %-22s %-24s %-24s %-24s' % ('code', 'loop times', 'whole-process wall', 'user CPU (load-robust)'))
    for l in rows:
        if l == ref:
            continue
        q = [sorted(runs[l][k][c] / runs[ref][k][c] for k in range(n)) for c in (0, 1, 2)]
        print('  %-22s %-24s %-24s %-24s' % (l, *('%.3f [%.3f, %.3f]' % (st.median(v), v[0], v[-1]) for v in q)))
PY
    echo "Terrace's phases (best runs):"
    for v in ar_terrace ar_terrace_mixed_tol ar_terrace_mixed_tol40 ar_terrace_tol_pruned ar_terrace_mixed_pruned; do
        echo "  $v: builds $(figure $v.best.summary.json neighbor/builds), skin $(figure $v.best.summary.json neighbor/skin) A$(
            [[ $v == ar_terrace_*_pruned ]] && echo ", outer skin $(figure $v.best.summary.json neighbor/outer_skin) A, prunes $(figure $v.best.summary.json neighbor/prunes)"), energy drift $(figure $v.best.summary.json conservation/energy_drift_per_atom_time) eV/atom/ps"
        phases $v
    done
    for v in ar_gromacs_mix ar_gromacs_dbl; do
        [[ -f $v.best.log ]] || continue
        echo "  $v: $(grep -m1 -E 'Changing nstlist' $v.best.log | sed 's/^ *//'); $(grep -E 'list: updated every' $v.best.log | head -2 | sed 's/^ *//' | tr '\n' ';')"
        echo "    neighbour search: $(awk '/^ Neighbor search/ {print $5 " calls, " $6 " s"}' $v.best.log | tail -1), force: $(awk '/^ Force  / {print $5 " s"}' $v.best.log | tail -1)"
    done
    if [[ -f ar_lammps.best.log ]]; then
        echo "  ar_lammps: $(grep -m1 '^Neighbor list builds' ar_lammps.best.log), Pair $(awk -F'|' '/^Pair /{gsub(/ /,"",$3); print $3}' ar_lammps.best.log | tail -1) s, Neigh $(awk -F'|' '/^Neigh /{gsub(/ /,"",$3); print $3}' ar_lammps.best.log | tail -1) s"
    fi
    echo "  temperature (mean over the thermo samples): Terrace $(awk -F, 'NR > 1 && $0 !~ /^#/ {s += $3; n++} END {if (n) printf "%.2f K", s / n}' argon_nvt_100ns.csv 2> /dev/null) (last run, ar_terrace_mixed_pruned)"
    echo
fi

# ---- the seven-atom cluster with its trajectory -----------------------------------------------------
if [[ "$parts" == *,cluster,* ]]; then
    ns="${CLUSTER_NS:-100}"
    [[ "$ns" =~ ^[1-9][0-9]*$ ]] || { echo "anchors: CLUSTER_NS must be a positive integer (ns)" >&2; exit 2; }
    echo "== seven-atom argon cluster, energy stepping, all pairs: $ns ns, a frame every 10 ps (input/argon_frozen_2d.nml)"
    cp "$repo/input/argon_frozen_2d.atoms" .
    sed -e "s/run_time=100000.0/run_time=${ns}000.0/" "$repo/input/argon_frozen_2d.nml" > cluster.nml
    codes=(terrace)
    if [[ -n "${CLUSTER_BASELINE:-}" ]]; then cp "$(realpath "$CLUSTER_BASELINE")" ./baseline; codes+=(baseline); fi
    : > cluster.txt
    for ((r = 1; r <= repeat; r++)); do
        for code in "${codes[@]}"; do
            rm -f argon_frozen_2d.h5 argon_frozen_2d.csv
            /usr/bin/time -f %e -o "wall_$code.txt" "./$code" cluster.nml > "cluster_$code.log" 2>&1 \
                || { tail "cluster_$code.log" >&2; exit 1; }
            j=cluster.summary.json
            echo "$code $(figure $j timing/loop_time_s) $(figure $j timing/events)" \
                 "$(for ph in Pair Comm Output Search Other; do figure $j timing/phases/$ph/avg_s; done | tr '\n' ' ')" \
                 "$(tail -1 "wall_$code.txt")" >> cluster.txt
        done
    done
    /usr/bin/python3 - cluster.txt "$ns" <<'PY'
import statistics, sys
rows = [l.split() for l in open(sys.argv[1]) if l.strip()]
frames = int(sys.argv[2]) * 100 + 1
print('%-9s %9s %9s %8s | %7s %7s %7s %7s %7s | %8s | %9s' % ('code', 'loop s', 'events', 'us/ev', 'Pair', 'Comm',
      'Output', 'Search', 'Other', 'us/frame', 'process s'))
med = {}
for code in dict.fromkeys(r[0] for r in rows):
    rs = [r for r in rows if r[0] == code]
    med[code] = statistics.median(float(r[1]) for r in rs)
    walls = sorted(float(r[8]) for r in rs)
    best = min(rs, key=lambda r: float(r[1]))
    ph = [float(x) for x in best[3:8]]
    print('%-9s %9.3f %9d %8.3f | %7.3f %7.3f %7.3f %7.3f %7.3f | %8.1f | %9.2f   (best of %d; median loop %.3f s, '
          'process %.2f [%.2f, %.2f] s)' % (
        code, float(best[1]), int(best[2]), 1e6 * float(best[1]) / int(best[2]), *ph, 1e6 * ph[2] / frames,
        float(best[8]), len(rs), med[code], statistics.median(walls), walls[0], walls[-1]))
print('(us/frame: the Output phase, frames and thermo samples, over the %d frames; process s: the whole '
      'process, /usr/bin/time, start-up and final output included)' % frames)
if 'baseline' in med:
    print('baseline / terrace, median loop times: %.2f' % (med['baseline'] / med['terrace']))
PY
    echo
fi
if [[ "${KEEP:-0}" == 1 ]]; then echo "work dir: $work"; fi
