#!/usr/bin/env bash
# Speed of two builds side by side (a refactoring must not slow the engine): the LAMMPS LJ
# benchmark scene (input/lj_bench.nml, 32,000 atoms) and the LAMMPS EAM scene (Cu_u3, 32,000 atoms,
# the in.eam set-up of scripts/bench/eam_bench.sh), one rank, OLD and NEW alternating, REPEAT times
# each; prints each loop time, the best of each build and new/old.
# COUNT=instructions: each build runs once per scene under `valgrind --tool=callgrind` and the
# whole process's instruction counts are compared instead (they repeat exactly on a machine too
# busy for wall times; use fewer steps, e.g. 100 and 20, so that it takes minutes).
# SCENES (default 'lj eam') adds others: lj_mixed (the LJ scene in mixed precision, over the list
# &neighbor list = 'auto' chooses: the atom list where the build has AVX-512), mix3 (the three-type LJ mixture of tests/regression/decks/es_mix3.nml, 864
# atoms, velocity Verlet, 10 x NSTEPS_LJ steps) and cuni (the 50/50 Cu-Ni eam/alloy of
# tests/regression/decks/cuni_es.data, 256 atoms, 10 x NSTEPS_EAM steps).
# FUNCS='REGEX ...' (with COUNT=instructions): also each build's inclusive count of the first
# function whose callgrind name matches each REGEX (e.g. 'cluster_list_MOD_cl_build').
# Usage: [COUNT=instructions] scripts/bench/old_new_speed.sh OLD_TERRACE NEW_TERRACE [NSTEPS_LJ [NSTEPS_EAM [REPEAT]]]
set -euo pipefail
old="$(realpath "$1")"; new="$(realpath "$2")"
nlj="${3:-1000}"; neam="${4:-200}"; repeat="${5:-3}"
repo="$(cd "$(dirname "${BASH_SOURCE[0]}")/../.." && pwd)"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT; cd "$work"
sed -e "s/n_steps=1000/n_steps=$nlj/" "$repo/input/lj_bench.nml" > lj.nml
cat > eam.nml <<NML
&run units='metal', dimension=3, n_steps=$neam, seed=87287 /
&system lattice='fcc', lattice_constant=3.615, cells=20,20,20, periodic=.true.,.true.,.true., temperature=1600.0 /
&potential style='eam', file='/usr/share/lammps/potentials/Cu_u3.eam' /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=1.0 /
&output thermo_every=50, thermo_file='' /
NML
sed -e "s/cutoff=2.5, shift=.false. \//cutoff=2.5, shift=.false., precision='mixed' \//" lj.nml > lj_mixed.nml
sed -e "s#@REPO@#$repo#" -e "s/n_steps=3000/n_steps=$((10 * nlj))/" \
    -e "s/style='energy_stepping', terrace_height=0.1/style='velocity_verlet', dt=0.004/" \
    -e "s/thermo_file='thermo.csv'/thermo_file=''/" "$repo/tests/regression/decks/es_mix3.nml" > mix3.nml
cat > cuni.nml <<NML
&run units='metal', dimension=3, n_steps=$((10 * neam)), seed=2021 /
&system read_data='$repo/tests/regression/decks/cuni_es.data' /
&potential style='eam/alloy', file='/usr/share/lammps/potentials/CuNi.eam.alloy', elements='Cu','Ni' /
&integrator style='velocity_verlet', dt=0.002 /
&neighbor skin=1.0 /
&output thermo_every=50, thermo_file='' /
NML
grep -q "precision='mixed'" lj_mixed.nml && grep -q "velocity_verlet" mix3.nml || { echo "old_new_speed: could not edit the decks" >&2; exit 1; }
scenes="${SCENES:-lj eam}"
echo "old: $old"; echo "new: $new"
echo "machine: $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1), $(nproc) cores visible, load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "date: $(date -u '+%Y-%m-%d %H:%M UTC')"
# the loop time from the run summary the deck writes beside it (lj.nml -> lj.summary.json; both
# builds must write run summaries)
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }
loop() { rm -f "${2%.nml}.summary.json"; "$1" "$2" > /dev/null 2>&1; figure "${2%.nml}.summary.json" timing/loop_time_s; }
if [[ "${COUNT:-}" == instructions ]]; then
  command -v valgrind > /dev/null || { echo "old_new_speed: valgrind is not installed" >&2; exit 2; }
  # a build with -march=native may use instructions valgrind cannot run (it stops with SIGILL after
  # start-up, and the count would be start-up only): configure both with -DTERRACE_PORTABLE=ON
  count() { valgrind --tool=callgrind --callgrind-out-file=cg_$3.out "$1" "$2" > /dev/null 2>cg.err || {
              echo "old_new_speed: $1 $2 failed under valgrind (a -march=native build? use -DTERRACE_PORTABLE=ON):" >&2
              tail -3 cg.err >&2; exit 2; }
            sed -n 's/^summary: *\([0-9]*\).*/\1/p' cg_$3.out | head -1; }
  # the inclusive count of the first function matching $2 in callgrind output $1
  # (awk reads to the end: an early exit would stop callgrind_annotate with SIGPIPE, and pipefail the script)
  inclusive() { callgrind_annotate --inclusive=yes "$1" 2> /dev/null | awk -v pat="$2" '!done && $0 ~ pat { gsub(/,/, "", $1); print $1; done = 1 }'; }
  for scene in $scenes; do
    io=$(count "$old" $scene.nml old); in=$(count "$new" $scene.nml new)
    awk -v s=$scene -v o="$io" -v n="$in" 'BEGIN{printf "%-8s old %.4e, new %.4e instructions, new/old = %.4f\n", s, o, n, n/o}'
    for f in ${FUNCS:-}; do
      fo=$(inclusive cg_old.out "$f"); fn=$(inclusive cg_new.out "$f")
      awk -v f="$f" -v o="${fo:-0}" -v n="${fn:-0}" 'BEGIN{ if (o > 0 && n > 0) printf "  %-40s old %.4e, new %.4e, new/old = %.4f\n", f, o, n, n/o }'
    done
  done
  exit 0
fi
for scene in $scenes; do
  best_old=1e30; best_new=1e30
  for r in $(seq "$repeat"); do
    to=$(loop "$old" $scene.nml); tn=$(loop "$new" $scene.nml)
    printf "  %s run %d: old %.4f s, new %.4f s\n" "$scene" "$r" "$to" "$tn"
    best_old=$(awk -v a="$best_old" -v b="$to" 'BEGIN{print (b<a)?b:a}')
    best_new=$(awk -v a="$best_new" -v b="$tn" 'BEGIN{print (b<a)?b:a}')
  done
  awk -v s=$scene -v o="$best_old" -v n="$best_new" 'BEGIN{printf "%-4s best old %.3f s, best new %.3f s, new/old = %.3f\n", s, o, n, n/o}'
done
