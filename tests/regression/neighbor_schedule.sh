#!/usr/bin/env bash
# The neighbour-list schedule (&neighbor every, check) on the 2048-atom LJ liquid deck (fcc 8x8x8
# melting at T* = 1.44, 100 steps, rc 2.5, skin 0.3):
#   1. a rebuild at every step (every = 1, check = .false.) gives the thermo of the exact default
#      (skin/2 test at every step) to 1e-10: both lists hold every pair within the cutoff, only
#      the order of the sums differs; none of its builds counts as late;
#   2. a fixed schedule (every = 20, check = .false., the LAMMPS bench's `neigh_modify every 20
#      check no`) rebuilds at steps 0, 20, ..., 100 (6 builds) on any rank count: 1 and 4 ranks
#      agree to 1e-10, and the run log counts the builds at which an atom had already moved more
#      than skin/2 (this hot start moves atoms ~0.5 sigma in 20 steps: 5 of the 5 rebuilds);
#   3. checked every 5 steps (every = 5): at most as many builds as the exact schedule, every one
#      of them at a multiple of 5 steps, the late ones counted;
#   4. energy stepping's pruned list follows the potential's runs_on_pruned_list (scene plan of
#      `terrace --check`): on for lj and lj/smooth/linear on this deck, off for EAM (its passes need
#      the list's complement) and for Verlet.
# Usage: tests/regression/neighbor_schedule.sh TERRACE_BINARY OUTPUT_DIR
source "$(dirname "${BASH_SOURCE[0]}")/liquid_common.sh" "$@"
deck() {   # name neighbor-keys
    sed "s|^&neighbor skin=0.3 /|\&neighbor skin=0.3$2 /|; s|thermo_file='thermo.csv'|thermo_file='$1.csv'|" \
        "$here/decks/liquid_2048.nml" > "$1.nml"
    grep -q "skin=0.3$2 /" "$1.nml" || { echo "FAIL: could not set '$2' in the deck"; exit 1; }
}
figure() { "$PYTHON" -m terrace_tools.summary get "$1.summary.json" "$2"; }   # the run summary's
builds() { figure "$1" neighbor/builds; }
late() { echo "$(figure "$1" neighbor/late_builds) $(figure "$1" neighbor/builds)"; }

deck exact ""
deck every1 ", every=1, check=.false."
deck fixed20 ", every=20, check=.false."
cp fixed20.nml fixed20_np4.nml; sed -i "s|fixed20.csv|fixed20_np4.csv|" fixed20_np4.nml
deck checked5 ", every=5"
run exact 1; run every1 1; run fixed20 1; run fixed20_np4 4; run checked5 1

# 1. rebuilding at every step changes nothing but the order of the sums
compare exact every1 "rebuild at every step = exact schedule (1e-10)"
[[ "$(builds every1)" == 101 ]] || { echo "FAIL: every = 1, check = .false. built $(builds every1) times, expected 101"; exit 1; }
[[ "$(late every1)" == "0 101" ]] || { echo "FAIL: every = 1 counted '$(late every1)' late builds (a rebuild at every step is never late)"; exit 1; }
figure exact neighbor/late_builds > /dev/null 2>&1 && { echo "FAIL: the exact schedule's summary counts late builds"; exit 1; }

# 2. fixed schedule: 6 builds, rank-count invariant, late builds counted
[[ "$(builds fixed20)" == 6 && "$(builds fixed20_np4)" == 6 ]] || {
    echo "FAIL: every = 20 built $(builds fixed20) (1 rank) and $(builds fixed20_np4) (4 ranks) times, expected 6"; exit 1; }
compare fixed20 fixed20_np4 "every = 20, check = .false.: 1 and 4 ranks agree (1e-10)"
read -r nlate nb <<< "$(late fixed20)"
[[ "$nb" == 6 && "$nlate" == 5 ]] || { echo "FAIL: every = 20 reported '$(late fixed20)' late of builds, expected '5 6'"; exit 1; }
echo "ok   every = 20, check = .false.: 6 builds, 5 late (atoms moved more than skin/2 within 20 steps)"
grep -q 'pairs .*rebuilt every 20 steps without a check (not exact' fixed20.log &&
    grep -q 'pairs .*checked every 5 steps and rebuilt when an atom has moved skin/2 (not exact' checked5.log &&
    grep -q 'pairs .*, rebuilt when an atom has moved skin/2, atoms sorted' exact.log ||
    { echo "FAIL: the scene plan does not state the list schedule"; grep -h 'pairs ' ./*.log; exit 1; }
echo "ok   the scene plan states each schedule"

# 3. checked every 5 steps: no more builds than the exact schedule, and late ones counted
ne="$(builds exact)"; n5="$(builds checked5)"; read -r l5 b5 <<< "$(late checked5)"
[[ "$n5" -le "$ne" && "$b5" == "$n5" && "$l5" -ge 1 && "$l5" -le $((n5 - 1)) ]] || {
    echo "FAIL: checked every 5: $n5 builds ($l5 late) against $ne exact"; exit 1; }
echo "ok   checked every 5 steps: $n5 builds ($l5 late) against $ne for the exact schedule"
for n in exact fixed20; do echo "     $n: energy drift $(figure $n conservation/energy_drift_per_atom_time) per atom per tau"; done

# 4. the pruned list: which potentials and integrators get it (the scene plan's pairs line)
es_deck() {   # name potential-line
    sed "s|^&potential .*|$2|; s|^&integrator .*|\&integrator style='energy_stepping', terrace_height=0.5 /|" \
        "$here/decks/liquid_2048.nml" > "$1.nml"
}
es_deck es_lj "\&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /"
es_deck es_ljs "\&potential style='lj/smooth/linear', epsilon=1.0, sigma=1.0, cutoff=2.5 /"
pruned() { timeout 120 "$terrace" --check "$1" 2>&1 | grep '^ *pairs ' | grep -c 'pruned from it' || true; }
[[ "$(pruned es_lj.nml)" == 1 && "$(pruned es_ljs.nml)" == 1 ]] ||
    { echo "FAIL: energy stepping with lj / lj/smooth/linear does not run on the pruned list"; exit 1; }
[[ "$(pruned "$here/decks/es_cu_eam_short.nml")" == 0 && "$(pruned exact.nml)" == 0 ]] ||
    { echo "FAIL: the pruned list is planned for EAM or for Verlet"; exit 1; }
echo "ok   pruned list planned for energy stepping with lj and lj/smooth/linear, not for EAM or Verlet"
