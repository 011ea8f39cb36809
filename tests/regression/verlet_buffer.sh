#!/usr/bin/env bash
# The Verlet buffer from an energy-drift tolerance (&neighbor buffer_tolerance, every = 20), on the
# 2048-atom LJ liquid deck (fcc 8x8x8 melting at T* = 1.44, rc 2.5, energy shifted at rc so that
# the total energy has no jumps), 4000 steps of NVE (20 tau):
#   1. the measured drift (the run summary's energy drift, per atom per tau) of the runs with
#      tolerance 1e-2 and 1e-3 lies within each tolerance; the smaller tolerance has the larger skin;
#   2. the same schedule without a buffer (skin = 0, every = 20) drifts at more than 10 times the
#      smaller tolerance (the missed pairs the buffer is there for: the check above can fail), and
#      the exact list (skin 0.3, the default schedule) within 1e-5;
#   3. 4 ranks size the same skin (the estimate is over the whole system) and run the same 100 steps
#      as 1 rank (1e-10); the scene plan states the tolerance, the estimate and the temperature;
#   4. with prune_every (every = 40, prune_every = 10, tolerance 1e-3: the list built with the skin
#      for 40 steps, the force pass's list pruned from it every 10 steps with the skin for 10 steps,
#      each for half the tolerance): the measured drift within 1e-3, the pass's skin smaller than the
#      built list's, 300 prunes in 4000 steps; 1 and 4 ranks the same skins and the same 100 steps;
#   5. the same with &potential precision = 'mixed' (the mixed kernel over the pruned atom list): the
#      run log names the mixed kernel, the skins are the double run's, 300 prunes, the measured
#      drift within 1e-3.
# Usage: tests/regression/verlet_buffer.sh TERRACE_BINARY OUTPUT_DIR
source "$(dirname "${BASH_SOURCE[0]}")/liquid_common.sh" "$@"
deck() {   # name steps neighbor-keys
    sed -e "s|^&neighbor skin=0.3 /|\&neighbor $3 /|" -e "s|n_steps=100|n_steps=$2|" \
        -e "s|cutoff=2.5 /|cutoff=2.5, shift=.true. /|" -e "s|thermo_file='thermo.csv'|thermo_file='$1.csv'|" \
        "$here/decks/liquid_2048.nml" > "$1.nml"
    grep -q "^&neighbor $3 /" "$1.nml" && grep -q "shift=.true." "$1.nml" || { echo "FAIL: could not edit the deck for $1"; exit 1; }
}
skin() { "$PYTHON" -m terrace_tools.summary get "$1.summary.json" neighbor/skin; }
drift() { "$PYTHON" -m terrace_tools.summary get "$1.summary.json" conservation/energy_drift_per_atom_time; }
within() { "$PYTHON" -c "import sys; sys.exit(not abs(float('$1')) <= float('$2'))"; }

deck tol2 4000 "every=20, buffer_tolerance=1e-2"
deck tol3 4000 "every=20, buffer_tolerance=1e-3"
deck bare 4000 "skin=0, every=20, check=.false."
deck exact 4000 "skin=0.3"
deck ranks1 100 "every=20, buffer_tolerance=1e-3"
deck pruned 4000 "every=40, prune_every=10, buffer_tolerance=1e-3"
deck pranks1 100 "every=40, prune_every=10, buffer_tolerance=1e-3"
sed -e "s|shift=.true. /|shift=.true., precision='mixed' /|" -e "s|pruned.csv|mpruned.csv|" pruned.nml > mpruned.nml
grep -q "precision='mixed'" mpruned.nml || { echo "FAIL: could not edit the deck for mpruned"; exit 1; }
cp pranks1.nml pranks4.nml; sed -i "s|pranks1.csv|pranks4.csv|" pranks4.nml
cp ranks1.nml ranks4.nml; sed -i "s|ranks1.csv|ranks4.csv|" ranks4.nml
for n in tol2 tol3 bare exact ranks1 pruned pranks1 mpruned; do run $n 1; done
run ranks4 4
run pranks4 4

# 1. measured drift within the tolerance
for t in 2 3; do
    s="$(skin tol$t)"; d="$(drift tol$t)"
    [[ -n "$s" && -n "$d" ]] || { echo "FAIL: no skin or drift in tol$t.log"; exit 1; }
    within "$d" "1e-$t" || { echo "FAIL: tolerance 1e-$t: skin $s, measured drift $d beyond it"; exit 1; }
    echo "ok   tolerance 1e-$t: skin $s, measured drift $d per atom per tau"
done
"$PYTHON" -c "import sys; sys.exit(not float('$(skin tol3)') > float('$(skin tol2)') > 0)" ||
    { echo "FAIL: skins $(skin tol2) (1e-2) and $(skin tol3) (1e-3) not ordered"; exit 1; }
echo "ok   the smaller tolerance has the larger skin"

# 2. without a buffer the same schedule drifts; the exact list does not
within "$(drift bare)" 1e-2 && { echo "FAIL: skin 0, every 20: drift $(drift bare) is not beyond 10 x 1e-3"; exit 1; }
within "$(drift exact)" 1e-5 || { echo "FAIL: the exact list drifts by $(drift exact)"; exit 1; }
echo "ok   skin 0 every 20 steps: drift $(drift bare); exact list: $(drift exact)"

# 3. rank count, and the scene plan
[[ "$(skin ranks1)" == "$(skin ranks4)" ]] || { echo "FAIL: skin $(skin ranks1) on 1 rank, $(skin ranks4) on 4"; exit 1; }
compare ranks1 ranks4 "1 and 4 ranks: skin $(skin ranks1), thermo the same (1e-10)"
grep -q 'rebuilt every 20 steps without a check, the skin sized for an energy drift of at most 1.000E-03 epsilon per atom per tau (&neighbor buffer_tolerance; estimate [0-9.]*E-0[34] at T = 1.44' ranks1.log ||
    { echo "FAIL: the scene plan does not state the tolerance"; grep 'pairs ' ranks1.log; exit 1; }
echo "ok   the scene plan states the tolerance, the estimate and the temperature"

# 4. prune_every: the drift, the two skins, the schedule, the rank count
get() { "$PYTHON" -m terrace_tools.summary get "$1.summary.json" "$2"; }
within "$(drift pruned)" 1e-3 || { echo "FAIL: prune_every: measured drift $(drift pruned) beyond 1e-3"; exit 1; }
"$PYTHON" -c "import sys; sys.exit(not 0 < float('$(skin pruned)') < float('$(get pruned neighbor/outer_skin)'))" ||
    { echo "FAIL: prune_every: skin $(skin pruned), outer skin $(get pruned neighbor/outer_skin)"; exit 1; }
[[ "$(get pruned neighbor/prunes)" == 300 && "$(get pruned neighbor/builds)" == 101 ]] ||
    { echo "FAIL: prune_every: $(get pruned neighbor/builds) builds and $(get pruned neighbor/prunes) prunes (101, 300)"; exit 1; }
echo "ok   prune_every 10, every 40: skins $(skin pruned) and $(get pruned neighbor/outer_skin), 300 prunes, measured drift $(drift pruned)"
[[ "$(skin pranks1) $(get pranks1 neighbor/outer_skin)" == "$(skin pranks4) $(get pranks4 neighbor/outer_skin)" ]] ||
    { echo "FAIL: prune_every: skins differ on 1 and 4 ranks"; exit 1; }
compare pranks1 pranks4 "prune_every on 1 and 4 ranks: the same skins, thermo the same (1e-10)"
grep -q 'pruned from it every 10 steps; rebuilt every 40 steps without a check, the skins sized for an energy drift of at most 1.000E-03 epsilon per atom per tau, half each' pranks1.log ||
    { echo "FAIL: the scene plan does not state the prune schedule"; grep 'pairs ' pranks1.log; exit 1; }
echo "ok   the scene plan states the prune schedule"

# 5. prune_every with the mixed-precision kernel
grep -q 'mixed precision' mpruned.log || { echo "FAIL: the mixed run's log does not name the mixed kernel"; exit 1; }
[[ "$(skin mpruned) $(get mpruned neighbor/outer_skin)" == "$(skin pruned) $(get pruned neighbor/outer_skin)" ]] ||
    { echo "FAIL: prune_every, mixed: skins $(skin mpruned), $(get mpruned neighbor/outer_skin) (double: $(skin pruned), $(get pruned neighbor/outer_skin))"; exit 1; }
[[ "$(get mpruned neighbor/prunes)" == 300 ]] || { echo "FAIL: prune_every, mixed: $(get mpruned neighbor/prunes) prunes (300)"; exit 1; }
within "$(drift mpruned)" 1e-3 || { echo "FAIL: prune_every, mixed: measured drift $(drift mpruned) beyond 1e-3"; exit 1; }
echo "ok   prune_every with precision = 'mixed': the double run's skins, 300 prunes, measured drift $(drift mpruned)"
