#!/usr/bin/env bash
# The I/O watchdog whichever rank is stuck: on 3 ranks, the test hook
# TERRACE_TEST_STALL_RANK=k makes rank k stop inside its first HDF5 slab write, as a rank stuck on
# a full device or a file system that does not answer would; the other ranks wait for it in HDF5's
# collectives or at the end of the section. For k = 0, 1 and 2, writing the trajectory and writing
# the checkpoint, the job must end non-zero within the time limit (TERRACE_IO_WATCHDOG_S=3: rank 0
# reports after 3 s, or, when it cannot, the next rank 3 s later), print exactly one
# 'terrace: error:' line naming the file, the &output key and the watchdog's reason, no crash text,
# and leave no process behind. 'k,blocked' also silences the stuck rank's own watchdog (SIGALRM
# ignored: a process that cannot run at all cannot report): with k = 0 another rank must report,
# which the test checks with mpirun --tag-output (the line comes from rank 1).
# A control run of the same deck without the hook must pass (exit 0).
#
# usage: io_watchdog_stall.sh TERRACE_BIN OUTPUT_DIR
set -u
terrace=$(readlink -f "$1")
out=$(mkdir -p "$2" && cd "$2" && pwd)
[ "$(id -u)" = 0 ] && export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
export TERRACE_IO_WATCHDOG_S=3
limit=40
fail=0

deck() { # KIND -> the deck for that output
    local o
    if [ "$1" = trajectory ]; then
        o="trajectory_file='t.h5', trajectory_every=5"
    else
        o="checkpoint_file='c.h5', checkpoint_every=10"
    fi
    cat << EOF
&run units='lj', n_steps=30, seed=1 /
&system lattice='fcc', density=0.8442, cells=4,4,4, mass=1.0, temperature=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&output thermo_every=5, $o /
EOF
}

# run KIND STALL: sets work, rc, secs
run() {
    work=$out/work_$1_${2//,/_}
    rm -rf "$work" && mkdir -p "$work"
    deck "$1" > "$work/deck.nml"
    local start
    start=$(date +%s)
    if [ "$2" = none ]; then
        (cd "$work" && timeout -k 5 "$limit" mpirun --oversubscribe -np 3 "$terrace" deck.nml) > "$work/out" 2> "$work/err"
        rc=$?
    else
        (cd "$work" && TERRACE_TEST_STALL_RANK=$2 timeout -k 5 "$limit" mpirun --oversubscribe --tag-output -np 3 \
            "$terrace" deck.nml) > "$work/out" 2> "$work/err.tagged"
        rc=$?
        # '[job,rank]<stderr>:line' -> the line; the rank that printed the error -> $work/reporter
        sed -E 's/^\[[0-9]+,[0-9]+\]<std(err|out)>://' "$work/err.tagged" > "$work/err"
        sed -n -E 's/^\[[0-9]+,([0-9]+)\]<stderr>:terrace: error.*/\1/p' "$work/err.tagged" | head -n 1 > "$work/reporter"
    fi
    secs=$(($(date +%s) - start))
}

# processes of this binary still running in the case's directory
leftovers() {
    local p
    for p in $(pgrep -x terrace); do
        [ "$(readlink "/proc/$p/cwd" 2> /dev/null)" = "$1" ] && printf '%s ' "$p"
    done
}

for kind in trajectory checkpoint; do
    run "$kind" none
    if [ "$rc" != 0 ]; then
        echo "FAIL  control ($kind, no stall): exit $rc: $(grep -m1 'terrace: error' "$work/err")"; fail=1
    else
        echo "ok    control ($kind, no stall): exit 0 after ${secs} s"
    fi
    if [ "$kind" = trajectory ]; then
        key=trajectory_file; stalls='0 1 2 0,blocked 1,blocked 2,blocked'
    else
        key=checkpoint_file; stalls='0 1 2 0,blocked'
    fi
    for k in $stalls; do
        want=0   # the rank that must report: 0, unless rank 0 is the stuck one and cannot
        [ "$k" = 0,blocked ] && want=1
        run "$kind" "$k"
        # (mpirun has returned: its ranks should be gone; a second for the slowest to vanish)
        for _ in 1 2 3 4 5 6 7 8 9 10; do
            left=$(leftovers "$work")
            [ -z "$left" ] && break
            sleep 0.1
        done
        nerr=$(grep -c '^terrace: error' "$work/err")
        msg=$(grep -m1 '^terrace: error' "$work/err")
        crash=$(cat "$work/out" "$work/err" | grep -m 1 -i -E 'backtrace|SIGSEGV|SIGBUS|SIGABRT|Program received signal|Segmentation fault|core dumped')
        if [ "$kind" = trajectory ]; then file="t.h5 ("; else file="c.h5 ("; fi
        why=''
        if [ "$rc" = 0 ] || [ "$rc" = 124 ] || [ "$rc" = 137 ]; then why="exit $rc (0: the stall was not seen; 124/137: hang)"
        elif [ -n "$crash" ]; then why="crash text: $crash"
        elif [ "$nerr" != 1 ]; then why="$nerr error lines"
        elif [[ $msg != *"$file"* || $msg != *"&output $key"* || $msg != *"did not finish on every rank"* ]]; then
            why="message: $msg"
        elif [ -n "$left" ]; then why="processes left running: $left"
        elif [ "$(cat "$work/reporter")" != "$want" ]; then why="rank $(cat "$work/reporter") reported, expected rank $want"
        fi
        if [ -z "$why" ]; then
            echo "ok    $kind, rank $k stuck: exit $rc after ${secs} s, reported by rank $want: $msg"
        else
            echo "FAIL  $kind, rank $k stuck: $why"; fail=1
            sed 's/^/      | /' "$work/err" | head -n 20
            for p in $left; do kill -9 "$p" 2> /dev/null; done
        fi
    done
done
exit $fail
