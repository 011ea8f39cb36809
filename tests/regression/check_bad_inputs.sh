#!/usr/bin/env bash
# Malformed-input regression: every case in bad_inputs/cases.txt must end with a non-zero exit
# (the expected one), no hang, exactly one stderr line starting with 'terrace: error' that holds
# every substring the manifest lists, and no file written into the working directory.
#
# usage: check_bad_inputs.sh TERRACE_BIN [NPROCS...]      (default NPROCS: 1 4)
#   NPROCS 1 runs the binary directly (singleton MPI); any other N runs `mpirun -np N`.
#   Environment: MPIRUN (default mpirun), MPIRUN_FLAGS (default --oversubscribe),
#   CASE_TIMEOUT (seconds, default 60), ONLY (run only the cases whose name matches this regex).
# Output: one line per case and rank count (ok / FAIL with the reason), then `N passed, M failed`.
# Exit status: 0 when all passed, 1 otherwise, 2 on bad usage.
#
# Open MPI prints its own boxes (lines between two rows of dashes) when a rank exits non-zero or
# calls MPI_Abort; those boxes are dropped before the stderr is checked, and a case whose boxes
# say MPI_ABORT is marked "(MPI_Abort)" in its line: such cases end through abort_all rather
# than the collective stop_all path.
set -u

if [ $# -lt 1 ]; then
    echo "usage: $0 TERRACE_BIN [NPROCS...]" >&2
    exit 2
fi
bin=$(readlink -f "$1") || { echo "$0: cannot resolve $1" >&2; exit 2; }
shift
if [ ! -x "$bin" ]; then
    echo "$0: $bin is not an executable" >&2
    exit 2
fi
if [ $# -gt 0 ]; then nprocs=("$@"); else nprocs=(1 4); fi

here=$(cd "$(dirname "$0")" && pwd)
cases_dir=$here/bad_inputs
manifest=$cases_dir/cases.txt
mpirun_cmd=${MPIRUN:-mpirun}
read -r -a mpirun_flags <<< "${MPIRUN_FLAGS:---oversubscribe}"
limit=${CASE_TIMEOUT:-60}
only=${ONLY:-}
if [ "$(id -u)" = 0 ]; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi

scratch=$(mktemp -d "${TMPDIR:-/tmp}/terrace_bad_inputs.XXXXXX")
trap 'rm -rf "$scratch"' EXIT
passed=0
failed=0

trim() { local s=$1; s=${s#"${s%%[![:space:]]*}"}; s=${s%"${s##*[![:space:]]}"}; printf '%s' "$s"; }

# run_case NAME NP ARGS...: run in a fresh directory holding a copy of the case's files;
# sets rc, work (the directory), err (the stderr file), before (its listing beforehand).
run_case() {
    local name=$1 np=$2
    shift 2
    work=$(mktemp -d "$scratch/work.XXXXXX")
    err=$scratch/stderr.$name.$np
    local out=$scratch/stdout.$name.$np
    if [ -d "$cases_dir/$name" ]; then cp -R "$cases_dir/$name/." "$work/"; fi
    before=$(cd "$work" && find . -mindepth 1 | LC_ALL=C sort)
    if [ "$np" = 1 ]; then
        (cd "$work" && exec timeout -k 10 "$limit" "$bin" "$@") > "$out" 2> "$err" < /dev/null
    else
        (cd "$work" && exec timeout -k 10 "$limit" "$mpirun_cmd" "${mpirun_flags[@]}" -np "$np" "$bin" "$@") \
            > "$out" 2> "$err" < /dev/null
    fi
    rc=$?
}

new_files() {
    local after
    after=$(cd "$work" && find . -mindepth 1 | LC_ALL=C sort)
    comm -13 <(printf '%s\n' "$before") <(printf '%s\n' "$after") | sed 's|^\./||' | paste -s -d ' ' -
}

# stderr without Open MPI's dash-delimited boxes, without the libevent warnings mpirun itself
# sometimes prints while its ranks exit ("[warn] Epoll ... Bad file descriptor"), and without blank
# lines
filtered_stderr() {
    awk '/^--------------------+$/ { inbox = !inbox; next } /^\[warn\] Epoll / { next } !inbox && NF > 0' "$1"
}

report() { # status, np, name, note
    if [ "$1" = ok ]; then
        passed=$((passed + 1))
        printf 'ok    np=%-2s %s%s\n' "$2" "$3" "$4"
    else
        failed=$((failed + 1))
        printf 'FAIL  np=%-2s %s: %s\n' "$2" "$3" "$4"
    fi
}

# --- control: a valid deck must run and write its outputs (proves the output check can see them)
for np in "${nprocs[@]}"; do
    [ -n "$only" ] && ! [[ control_ok =~ $only ]] && continue
    run_case control_ok "$np" control_ok.nml
    left=$(new_files)
    if [ "$rc" -ne 0 ]; then
        report FAIL "$np" control_ok "the valid control deck exited $rc: $(filtered_stderr "$err" | head -n 1)"
    elif [[ " $left " != *" thermo.csv "* || " $left " != *" forces.txt "* ]]; then
        report FAIL "$np" control_ok "the valid control deck did not write thermo.csv and forces.txt (wrote: $left)"
    else
        report ok "$np" control_ok " (valid deck: exit 0, wrote $left)"
    fi
done

# --- the malformed cases
while IFS= read -r raw || [ -n "$raw" ]; do
    line=$(trim "${raw%%#*}")
    [ -z "$line" ] && continue
    IFS='|' read -r f_name f_exit f_args f_subs <<< "$line"
    name=$(trim "$f_name")
    want_rc=$(trim "$f_exit")
    read -r -a args <<< "$f_args"
    [ -n "$only" ] && ! [[ $name =~ $only ]] && continue
    for np in "${nprocs[@]}"; do
        run_case "$name" "$np" "${args[@]}"
        left=$(new_files)
        note=''
        grep -q 'MPI_ABORT' "$err" && note=' (MPI_Abort)'
        errors=$(filtered_stderr "$err" | grep -c '^terrace: error')
        msg=$(filtered_stderr "$err" | grep -m 1 '^terrace: error')
        extra=$(filtered_stderr "$err" | grep -v -e '^terrace: error' -e '^terrace: warning' | head -n 1)
        why=''
        if [ "$rc" -eq 124 ] || [ "$rc" -eq 137 ]; then
            why="hang: killed after ${limit} s (exit $rc)"
        elif [ "$rc" -eq 0 ]; then
            why='exit status 0 for a malformed input'
        elif [ "$rc" -ne "$want_rc" ]; then
            why="exit status $rc, expected $want_rc"
        elif [ "$errors" -ne 1 ]; then
            why="$errors lines start with 'terrace: error' (expected exactly 1)"
        elif [ -n "$extra" ]; then
            why="unexpected stderr line: $extra"
        fi
        if [ -z "$why" ]; then
            missing=()
            IFS=$'\x1f' read -r -a subs <<< "${f_subs// ; /$'\x1f'}"
            for s in "${subs[@]}"; do
                s=$(trim "$s")
                [ -z "$s" ] && continue
                [[ $msg == *"$s"* ]] || missing+=("[$s]")
            done
            [ ${#missing[@]} -gt 0 ] && why="message lacks ${missing[*]}"
        fi
        if [ -z "$why" ] && [ -n "$left" ]; then
            why="files left in the working directory: $left"
        fi
        if [ -z "$why" ]; then
            report ok "$np" "$name" "$note"
        else
            [ -n "$msg" ] && why="$why | $msg"
            report FAIL "$np" "$name" "$why$note"
        fi
    done
done < "$manifest"

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
