#!/usr/bin/env bash
# Run-away schedule guards: each deck below would never finish (a calendar interval far below the
# time the atoms need to move, in a run counted in events or bounded by run_time; an interval below
# half a Verlet step). Each is refused or stopped within one second on one rank (the best of three
# tries, so that a moment of load on a shared machine does not decide it), with exit status 1, one
# error line naming the key and the interval, and no thermo file; on 3 ranks with the same line.
# usage: runaway_guards.sh TERRACE_BIN OUTPUT_DIR
set -u
terrace=$(readlink -f "$1")
out=$2
rm -rf "$out" && mkdir -p "$out" && cd "$out" || exit 1
[ "$(id -u)" = 0 ] && export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
head='&system lattice='"'"'fcc'"'"', density=0.8442, cells=3,3,3, mass=1.0, temperature=1.0 /
&potential style='"'"'lj'"'"', epsilon=1.0, sigma=1.0, cutoff=2.5, shift=.true. /'
es="&integrator style='energy_stepping', terrace_height=0.05 /"
deck() { # NAME RUN INTEGRATOR OUTPUT [MORE]
    printf '&run units='"'"'lj'"'"', dimension=3, %s, seed=1 /\n%s\n%s\n&output thermo_file='"'"'thermo.csv'"'"', %s /\n%s\n' \
        "$2" "$head" "$3" "$4" "${5:-}" > "$1.nml"
}
deck es_thermo "n_steps=100" "$es" "thermo_interval=1e-20"
deck es_andersen "n_steps=100" "$es" "thermo_every=10" "&thermostat style='andersen', temperature=1.0, damping=1e-21 /"
deck es_csvr "n_steps=100" "$es" "thermo_every=10" \
    "&thermostat style='csvr', temperature=1.0, damping=0.5, interval=1e-22 /"
deck es_mc "n_steps=100" "$es" "thermo_every=10" "&thermostat style='andersen', temperature=1.0, damping=0.5 /
&barostat style='mc', pressure=1.0, interval=1e-22 /"
deck es_mc_run_time "run_time=1.0" "$es" "thermo_interval=0.5" \
    "&thermostat style='andersen', temperature=1.0, damping=0.5 /
&barostat style='mc', pressure=1.0, interval=1e-25 /"
deck vv_thermo "n_steps=100" "&integrator style='velocity_verlet', dt=0.005 /" "thermo_interval=1e-20"
want() { # NAME -> the words the message must hold
    case $1 in
        es_thermo) echo "thermo_interval|1.000E-20|would not finish" ;;
        es_andersen) echo "&thermostat|would not finish" ;;
        es_csvr) echo "&thermostat|would not finish" ;;
        es_mc) echo "&barostat interval|1.000E-22|would not finish" ;;
        es_mc_run_time) echo "&barostat|interval|volume moves|would not finish" ;;
        vv_thermo) echo "thermo_interval|1.000E-20|half a time step" ;;
    esac
}
fail=0
for name in es_thermo es_andersen es_csvr es_mc es_mc_run_time vv_thermo; do
    best=99
    for try in 1 2 3; do
        rm -f thermo.csv
        start=$(date +%s.%N)
        timeout 60 "$terrace" "$name.nml" > "$name.out" 2> "$name.err"
        rc=$?
        end=$(date +%s.%N)
        wall=$(awk -v a="$start" -v b="$end" 'BEGIN { printf "%.3f", b - a }')
        best=$(awk -v a="$best" -v b="$wall" 'BEGIN { print (b < a ? b : a) }')
        awk -v w="$best" 'BEGIN { exit !(w < 1.0) }' && break
    done
    msg=$(grep -m1 '^terrace: error' "$name.err")
    why=''
    [ "$rc" = 1 ] || why="exit $rc"
    IFS='|' read -r -a words <<< "$(want "$name")"
    for w in "${words[@]}"; do [[ $msg == *"$w"* ]] || why="$why; message lacks '$w'"; done
    [ -e thermo.csv ] && why="$why; thermo.csv left"
    awk -v w="$best" 'BEGIN { exit !(w < 1.0) }' || why="$why; took $best s (best of 3)"
    timeout 120 mpirun --oversubscribe -np 3 "$terrace" "$name.nml" > "$name.out3" 2> "$name.err3"
    rc3=$?
    msg3=$(grep -m1 '^terrace: error' "$name.err3")
    [ "$rc3" = 1 ] && [ "$(grep -c '^terrace: error' "$name.err3")" = 1 ] && [ "$msg3" = "$msg" ] \
        || why="$why; 3 ranks: exit $rc3, '$msg3'"
    if [ -z "$why" ]; then
        echo "ok    $name: stopped in $best s (1 rank; 3 ranks the same line): $msg"
    else
        echo "FAIL  $name:$why | $msg"; fail=1
    fi
done
[ $fail = 0 ] && echo "runaway_guards: PASS" || echo "runaway_guards: FAIL"
exit $fail
