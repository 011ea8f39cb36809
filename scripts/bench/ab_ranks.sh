#!/usr/bin/env bash
# Two Terrace binaries (OLD, NEW) on the same machine at several rank counts, alternating: each round
# runs every deck at every rank count with OLD, then NEW, so that a load that drifts (a shared host)
# weighs on both runs of a pair. One line per run (loop time; Pair, Neigh, Comm average/slowest rank),
# then scripts/bench/ab_ranks_report.py's summary: per binary, rank count and deck the lowest and
# median loop time, OLD/NEW per round (paired) and their median, and each binary's speed-up from one
# rank. For telling a change of the code from a change of the machine's day where one run per point
# (scaling.sh) cannot.
#
# Usage: scripts/bench/ab_ranks.sh OLD_BINARY NEW_BINARY DECK.nml [DECK.nml...]
# Environment: ROUNDS (3), RANKS ("16 8 1"), MPIRUN (mpirun), MPI_FLAGS ("--map-by core --bind-to core"),
#   OUTDIR (the run logs and summaries; default a temp dir). Decks run from their own directory.
# Used on the 16-core machine through scripts/bench/bundle.sh run (doc/performance.md, "Parallel runs").
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
[[ $# -ge 3 ]] || { sed -n '2,13p' "${BASH_SOURCE[0]}" >&2; exit 2; }
old="$(realpath "$1")"; new="$(realpath "$2")"; shift 2
for b in "$old" "$new"; do [[ -x "$b" ]] || { echo "ab_ranks: $b is not an executable" >&2; exit 2; }; done
rounds="${ROUNDS:-3}"; ranks="${RANKS:-16 8 1}"; mpirun="${MPIRUN:-mpirun}"
flags="${MPI_FLAGS:---map-by core --bind-to core}"
out="${OUTDIR:-$(mktemp -d)}"; mkdir -p "$out"
# the figures come from each run's summary (the deck's name with .summary.json, beside the deck),
# kept beside its log
figure() { PYTHONPATH="$here/..${PYTHONPATH:+:$PYTHONPATH}" python3 -m terrace_tools.summary get "$@"; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1 OMP_NUM_THREADS=1
echo "machine: $(lscpu | sed -n 's/^Model name: *//p' | head -1); date $(date -u '+%F %T UTC'); old = $old, new = $new"
for ((r = 1; r <= rounds; r++)); do
    for np in $ranks; do
        for deck in "$@"; do
            name="$(basename "$deck" .nml)"
            for b in old new; do
                if [[ $b == old ]]; then bin=$old; else bin=$new; fi
                log="$out/r${r}_np${np}_${name}_$b.log"
                # shellcheck disable=SC2086
                if ! (cd "$(dirname "$deck")" && "$mpirun" $flags -np "$np" "$bin" "$(basename "$deck")") > "$log" 2>&1; then
                    echo "FAILED $log"; tail -3 "$log"; continue; fi
                sum="${log%.log}.summary.json"
                cp "$(dirname "$deck")/$name.summary.json" "$sum"
                loop=$(figure "$sum" timing/loop_time_s)
                ph=$(for p in Pair Neigh Comm; do
                         printf ' %s %.4f/%.4f' $p "$(figure "$sum" timing/phases/$p/avg_s)" "$(figure "$sum" timing/phases/$p/max_s)"
                     done)
                printf 'r%d np%2d %-14s %-3s loop %7.3f s |%s\n' "$r" "$np" "$name" "$b" "$loop" "$ph"
            done
        done
    done
done | tee "$out/ab_ranks.txt"
echo
python3 "$here/ab_ranks_report.py" "$out/ab_ranks.txt"
