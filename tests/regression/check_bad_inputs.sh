#!/usr/bin/env bash
# Malformed-input regression: every case in bad_inputs/cases.txt must end with a non-zero exit
# (the expected one), no hang, exactly one stderr line starting with 'terrace: error' that holds
# every substring the manifest lists, and no file written into the working directory.
#
# usage: check_bad_inputs.sh [--hostile] TERRACE_BIN [NPROCS...]      (default NPROCS: 1 4)
#   --hostile: run the cases that bad_inputs/generate_hostile.py generates (NaN and Inf,
#   counts beyond the file, scenes beyond memory, long paths, colliding and special outputs, locks,
#   ...) instead of bad_inputs/cases.txt. The generator needs numpy and h5py (damaged H5MD
#   trajectories): it runs with $TERRACE_PYTHON, else the first of /usr/bin/python3 and python3 that
#   has them (scripts/install_deps.sh installs python3-h5py); with none, the test fails saying so.
# A case whose arguments start with '@analyze' runs terrace-analyze (beside TERRACE_BIN) with the
# rest of them instead of the engine; its error line starts with 'terrace: error' likewise.
# Every case also must: print no crash text (Backtrace, SIGSEGV, 'Error allocating', ...) on stdout
# or stderr, and leave every file that was in its directory beforehand byte-identical.
# Cases run in parallel (JOBS at a time, default: the number of processors).
#   NPROCS 1 runs the binary directly (singleton MPI); any other N runs `mpirun -np N`.
#   Environment: MPIRUN (default mpirun), MPIRUN_FLAGS (default --oversubscribe),
#   CASE_TIMEOUT (seconds, default 60), ONLY (run only the cases whose name matches this regex).
# Output: one line per case and rank count (ok / FAIL with the reason; the case's wall time in
# brackets), then `N passed, M failed`.
# Exit status: 0 when all passed, 1 otherwise, 2 on bad usage.
#
# Open MPI prints its own boxes (lines between two rows of dashes) when a rank exits non-zero or
# calls MPI_Abort; those boxes are dropped before the stderr is checked, and a case whose boxes
# say MPI_ABORT is marked "(MPI_Abort)" in its line: such cases end through abort_all rather
# than the collective stop_all path.
set -u

hostile=0
if [ "${1:-}" = --hostile ]; then hostile=1; shift; fi
if [ $# -lt 1 ]; then
    echo "usage: $0 [--hostile] TERRACE_BIN [NPROCS...]" >&2
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
jobs_max=${JOBS:-$(nproc 2> /dev/null || echo 2)}
mpirun_cmd=${MPIRUN:-mpirun}
read -r -a mpirun_flags <<< "${MPIRUN_FLAGS:---oversubscribe}"
limit=${CASE_TIMEOUT:-60}
only=${ONLY:-}
if [ "$(id -u)" = 0 ]; then
    export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
fi

scratch=$(mktemp -d "${TMPDIR:-/tmp}/terrace_bad_inputs.XXXXXX")
trap 'chmod -R u+rwx "$scratch" 2> /dev/null; rm -rf "$scratch"' EXIT
analyze=$(dirname "$bin")/terrace-analyze
if [ "$hostile" = 1 ]; then
    cases_dir=$scratch/hostile_cases
    py=''
    for p in ${TERRACE_PYTHON:-} /usr/bin/python3 python3; do
        if "$p" -c 'import h5py, numpy' 2> /dev/null; then py=$p; break; fi
    done
    if [ -z "$py" ]; then
        echo "$0: no python with h5py and numpy (set TERRACE_PYTHON, or run scripts/install_deps.sh):" \
            "the damaged-trajectory cases cannot be generated" >&2
        exit 2
    fi
    PYTHONPATH="$here/../../scripts${PYTHONPATH:+:$PYTHONPATH}" "$py" "$here/bad_inputs/generate_hostile.py" "$cases_dir" > /dev/null || { echo "$0: generator failed" >&2; exit 2; }
    manifest=$cases_dir/cases.txt
    cp -a "$here/bad_inputs/control_ok" "$cases_dir/"
fi
passed=0
failed=0

# trim_to VAR STRING: VAR = STRING without its leading and trailing blanks
trim_to() { local _t=$2; _t=${_t#"${_t%%[![:space:]]*}"}; _t=${_t%"${_t##*[![:space:]]}"}; printf -v "$1" '%s' "$_t"; }

# The harness forks as little as it can per case (a case at one rank costs about as much as its
# checks did otherwise): listings by glob, the stderr and stdout read and filtered in the shell.
[ -n "${EPOCHREALTIME:-}" ] || { echo "$0: needs bash 5 or later (EPOCHREALTIME)" >&2; exit 2; }
shopt -s globstar dotglob nullglob
declare -A before=()

# list_dir DIR: LIST = every path under DIR (relative to it, directories too, symbolic links not
# followed), as `find DIR -mindepth 1` finds them
list_dir() {
    local p
    LIST=()
    for p in "$1"/**; do
        [ "$p" = "$1/" ] || LIST+=("${p#"$1"/}")
    done
}

# run_case NAME NP ARGS...: run in a fresh directory holding a copy of the case's files;
# sets rc, work (the directory), err (the stderr file), out, before (its listing beforehand, an
# associative array), files (its regular readable files) and sums (their checksums). A case
# directory with '.hold_lock' runs while another process holds an flock on the lock file it names.
run_case() {
    local name=$1 np=$2 holder='' exe=$bin p
    shift 2
    if [ "${1:-}" = @analyze ]; then exe=$analyze; shift; fi
    work=$scratch/work.$name.$np
    mkdir "$work" 2> /dev/null || work=$(mktemp -d "$scratch/work.XXXXXX")
    err=$scratch/stderr.$name.$np
    out=$scratch/stdout.$name.$np
    if [ -d "$cases_dir/$name" ]; then cp -a "$cases_dir/$name/." "$work/"; fi
    if [ -f "$work/.hold_lock" ]; then      # another run holding the lock: this shell, until the case ends
        local lock
        read -r lock < "$work/.hold_lock"
        exec {holder}> "$work/$lock"
        flock -n "$holder" || echo "check_bad_inputs: could not take the lock of $name" >&2
    fi
    list_dir "$work"
    before=()
    files=()
    for p in "${LIST[@]}"; do
        before[$p]=1
        if [[ -f $work/$p && ! -L $work/$p && -r $work/$p ]]; then files+=("$p"); fi
    done
    sums=''
    if [ ${#files[@]} -gt 0 ]; then sums=$(cd "$work" && md5sum -- "${files[@]}"); fi
    if [ "$np" = 1 ]; then
        (cd "$work" && exec timeout -k 10 "$limit" "$exe" "$@") > "$out" 2> "$err" < /dev/null
    else
        (cd "$work" && exec timeout -k 10 "$limit" "$mpirun_cmd" "${mpirun_flags[@]}" -np "$np" "$exe" "$@") \
            > "$out" 2> "$err" < /dev/null
    fi
    rc=$?
    if [ -n "$holder" ]; then exec {holder}>&-; fi
}

# the files of run_case's list that are gone, no longer regular files, or hold other bytes
changed_files() {
    local p line now=() gone=() changed=()
    local -A had=()
    [ ${#files[@]} -eq 0 ] && return
    while IFS= read -r line; do had[$line]=1; done <<< "$sums"
    for p in "${files[@]}"; do
        if [[ -f $work/$p && ! -L $work/$p && -r $work/$p ]]; then now+=("$p"); else gone+=("$p"); fi
    done
    if [ ${#now[@]} -gt 0 ]; then
        while IFS= read -r line; do
            [ -n "$line" ] && [ -z "${had[$line]:-}" ] && changed+=("${line#*  }")
        done <<< "$(cd "$work" && md5sum -- "${now[@]}" 2> /dev/null)"
    fi
    changed+=("${gone[@]}")
    printf '%s' "${changed[*]}"
}

# the paths under the case's directory that were not there beforehand
new_files() {
    local p added=()
    list_dir "$work"
    for p in "${LIST[@]}"; do
        [ -n "${before[$p]:-}" ] || added+=("$p")
    done
    printf '%s' "${added[*]}"
}

# read_stderr FILE: from its lines without Open MPI's dash-delimited boxes, without the libevent
# warnings mpirun itself sometimes prints while its ranks exit ("[warn] Epoll ... Bad file
# descriptor"), and without blank lines: errors (the count of lines starting with 'terrace:
# error'), msg (the first of them), extra (the first line that is neither an error nor a warning);
# aborted=1 when a box says MPI_ABORT
read_stderr() {
    local line inbox=0
    errors=0; msg=''; extra=''; aborted=0
    while IFS= read -r line || [ -n "$line" ]; do
        [[ $line == *MPI_ABORT* ]] && aborted=1
        if [[ $line =~ ^-{20,}$ ]]; then inbox=$((1 - inbox)); continue; fi
        [ $inbox = 1 ] && continue
        [[ $line == "[warn] Epoll "* || ! $line =~ [^[:space:]] ]] && continue
        if [[ $line == "terrace: error"* ]]; then
            errors=$((errors + 1))
            [ -z "$msg" ] && msg=$line
        elif [[ $line != "terrace: warning"* && -z $extra ]]; then
            extra=$line
        fi
    done < "$1"
}

# the first line of stdout or stderr with crash text (case-insensitive), if any
crash_text() {
    local f line
    for f in "$out" "$err"; do
        while IFS= read -r line || [ -n "$line" ]; do
            if [[ ${line,,} =~ backtrace|sigsegv|sigbus|sigabrt|error\ allocating|program\ received\ signal|segmentation\ fault|killed|core\ dumped ]]; then
                printf '%s' "$line"
                return
            fi
        done < "$f"
    done
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
        read_stderr "$err"
        report FAIL "$np" control_ok "the valid control deck exited $rc: ${msg:-$extra}"
    elif [[ " $left " != *" thermo.csv "* || " $left " != *" forces.txt "* ]]; then
        report FAIL "$np" control_ok "the valid control deck did not write thermo.csv and forces.txt (wrote: $left)"
    else
        report ok "$np" control_ok " (valid deck: exit 0, wrote $left)"
    fi
done

# --- the malformed cases: one job per case and rank count, JOBS at a time; each job writes its
# report line to a file of its own, printed in manifest order at the end
check_case() { # name np want_rc subs args...
    local name=$1 np=$2 want_rc=$3 f_subs=$4
    shift 4
    local t0 t1
    t0=${EPOCHREALTIME/[.,]/}
    run_case "$name" "$np" "$@"
    t1=${EPOCHREALTIME/[.,]/}
    note=" [$(( (t1 - t0) / 1000 )) ms]"
    left=$(new_files)
    read_stderr "$err"
    [ "$aborted" = 1 ] && note=' (MPI_Abort)'"$note"
    crash=$(crash_text)
    why=''
    if [ "$rc" -eq 124 ] || [ "$rc" -eq 137 ]; then
        why="hang: killed after ${limit} s (exit $rc)"
    elif [ "$rc" -eq 0 ]; then
        why='exit status 0 for a malformed input'
    elif [ -n "$crash" ]; then
        why="crash text: $crash"
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
            trim_to s "$s"
            [ -z "$s" ] && continue
            [[ $msg == *"$s"* ]] || missing+=("[$s]")
        done
        [ ${#missing[@]} -gt 0 ] && why="message lacks ${missing[*]}"
    fi
    if [ -z "$why" ] && [ -n "$left" ]; then
        why="files left in the working directory: $left"
    fi
    if [ -z "$why" ]; then
        changed=$(changed_files)
        [ -n "$changed" ] && why="pre-existing files changed or removed: $changed"
    fi
    if [ -z "$why" ]; then
        printf 'ok    np=%-2s %s%s\n' "$np" "$name" "$note"
    else
        [ -n "$msg" ] && why="$why | ${msg:0:400}"
        printf 'FAIL  np=%-2s %s: %s\n' "$np" "$name" "$why$note"
    fi
}

results=$scratch/results
mkdir -p "$results"
seq_no=0
running=0
while IFS= read -r raw || [ -n "$raw" ]; do
    trim_to line "${raw%%#*}"
    [ -z "$line" ] && continue
    IFS='|' read -r f_name f_exit f_args f_subs <<< "$line"
    trim_to name "$f_name"
    trim_to want_rc "$f_exit"
    read -r -a args <<< "$f_args"
    [ -n "$only" ] && ! [[ $name =~ $only ]] && continue
    for np in "${nprocs[@]}"; do
        seq_no=$((seq_no + 1))
        if [ "$running" -ge "$jobs_max" ]; then wait -n; running=$((running - 1)); fi
        running=$((running + 1))
        check_case "$name" "$np" "$want_rc" "$f_subs" "${args[@]}" > "$results/$(printf '%06d' "$seq_no")" < /dev/null &
    done
done < "$manifest"
wait
for f in "$results"/*; do
    [ -e "$f" ] || continue
    first=''
    while IFS= read -r line || [ -n "$line" ]; do
        [ -z "$first" ] && first=$line
        printf '%s\n' "$line"
    done < "$f"
    if [[ $first == ok* ]]; then passed=$((passed + 1)); else failed=$((failed + 1)); fi
done

echo "$passed passed, $failed failed"
[ "$failed" -eq 0 ]
