#!/usr/bin/env bash
# LJ benchmark: LAMMPS (scripts/bench/in.lj_bench) vs Terrace (input/lj_bench.nml),
# 32,000 atoms, fcc rho*=0.8442, T*=1.44, lj/cut 2.5, skin 0.3, NVE dt 0.005.
#
# Usage: scripts/bench/lj_bench.sh [NSTEPS [TERRACE_BINARY]]
#        defaults: NSTEPS=1000, TERRACE_BINARY=build/terrace (relative to repo root)
#
# Both codes run on 1 rank, 1 thread. Timing: LAMMPS's own "Loop time of X"
# line; Terrace's loop time from its run summary if it writes one, otherwise the
# wall time of the whole Terrace process (includes setup; reported as such).
# Prints atom-steps/s for each and the ratio Terrace/LAMMPS (>1: Terrace faster).
#
# Environment (optional): LMP (default lmp), TERRACE_LAUNCHER (e.g. "mpirun -np 1"),
# REPEAT=N to run the pair (LAMMPS then Terrace, back to back) N times and compare the best
# loop time of each (for noisy, shared machines; default 1), KEEP=1 to keep the work directory.
# With GNU time (/usr/bin/time) each line also shows the user CPU time of the process.
# Terrace's phase table (Pair, Neigh, Comm, ...) of its best run is printed at the end.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
# the run summary's figures (scripts/terrace_tools)
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }

nsteps="${1:-1000}"
terrace="${2:-$repo/build/terrace}"
LMP="${LMP:-lmp}"
natoms=32000

if ! [[ "$nsteps" =~ ^[0-9]+$ ]] || [[ "$nsteps" -eq 0 ]]; then
    echo "usage: $0 [NSTEPS [TERRACE_BINARY]]  (NSTEPS a positive integer)" >&2
    exit 2
fi

work="$(mktemp -d "${TMPDIR:-/tmp}/lj_bench.XXXXXX")"
if [[ "${KEEP:-0}" != 1 ]]; then
    trap 'rm -rf "$work"' EXIT
fi
ncores="$(nproc 2>/dev/null || echo '?')"
export OMP_NUM_THREADS=1

model="$(lscpu 2>/dev/null | sed -n 's/^Model name:[[:space:]]*//p' | head -n 1)"
commit="$(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "LJ benchmark: $natoms atoms, $nsteps steps, 1 rank"
echo "machine : ${model:-unknown} (${ncores} cores visible)"
echo "date    : $(date -u '+%Y-%m-%d %H:%M:%S UTC')"
echo "commit  : $commit"
echo

# rate = natoms * nsteps / seconds
rate() { awk -v n="$natoms" -v s="$nsteps" -v t="$1" 'BEGIN { printf "%.4e", n * s / t }'; }
repeat="${REPEAT:-1}"
if ! [[ "$repeat" =~ ^[0-9]+$ ]] || [[ "$repeat" -eq 0 ]]; then
    echo "REPEAT must be a positive integer" >&2
    exit 2
fi
timer=()
if [[ -x /usr/bin/time ]]; then timer=(/usr/bin/time -f '%U' -o user.txt); fi
user() { if [[ -s "$work/user.txt" ]]; then printf '  user %8.2f s' "$(tail -n 1 "$work/user.txt")"; fi; }

have_lmp=0
if command -v "$LMP" >/dev/null 2>&1; then have_lmp=1; else
    echo "LAMMPS  : '$LMP' not found (Debian package 'lammps'); skipped"
fi
have_ter=0
if [[ -x "$terrace" ]]; then
    have_ter=1
    terrace="$(cd "$(dirname "$terrace")" && pwd)/$(basename "$terrace")"
    sed -E "s/n_steps=[0-9]+/n_steps=$nsteps/" "$repo/input/lj_bench.nml" > "$work/lj_bench.nml"
else
    echo "Terrace : binary '$terrace' not found; skipped"
fi

lmp_best=""; ter_best=""; ter_how="loop time"
for ((rep = 1; rep <= repeat; rep++)); do
    tag=""
    if [[ "$repeat" -gt 1 ]]; then tag=" [$rep/$repeat]"; fi
    # ---- LAMMPS --------------------------------------------------------------
    if [[ $have_lmp == 1 ]]; then
        rm -f "$work/user.txt"
        (cd "$work" && "${timer[@]}" "$LMP" -screen none -log lammps.log -var nsteps "$nsteps" \
            -in "$here/in.lj_bench") || { echo "LAMMPS run failed:" >&2; tail -n 20 "$work/lammps.log" >&2; exit 1; }
        lmp_t="$(sed -n 's/^Loop time of \([0-9.eE+-]*\) on .* for '"$nsteps"' steps.*/\1/p' "$work/lammps.log" | tail -n 1)"
        if [[ -z "$lmp_t" ]]; then
            echo "could not find LAMMPS 'Loop time' line in $work/lammps.log" >&2
            exit 1
        fi
        printf 'LAMMPS  : loop time %10.4f s   %s atom-steps/s%s%s\n' "$lmp_t" "$(rate "$lmp_t")" "$(user)" "$tag"
        if [[ -z "$lmp_best" ]] || awk -v a="$lmp_t" -v b="$lmp_best" 'BEGIN { exit !(a < b) }'; then lmp_best=$lmp_t; fi
    fi
    # ---- Terrace -------------------------------------------------------------
    if [[ $have_ter == 1 ]]; then
        rm -f "$work/user.txt"
        t0="$(date +%s.%N)"
        # shellcheck disable=SC2086  # TERRACE_LAUNCHER is deliberately word-split
        (cd "$work" && "${timer[@]}" ${TERRACE_LAUNCHER:-} "$terrace" lj_bench.nml > terrace.log 2>&1) \
            || { echo "Terrace run failed:" >&2; tail -n 20 "$work/terrace.log" >&2; exit 1; }
        t1="$(date +%s.%N)"
        ter_t="$(figure "$work/lj_bench.summary.json" timing/loop_time_s 2> /dev/null || true)"
        ter_how="loop time"
        if [[ -z "$ter_t" ]]; then
            ter_t="$(awk -v a="$t0" -v b="$t1" 'BEGIN { printf "%.6f", b - a }')"
            ter_how="wall time"
        fi
        printf 'Terrace : %-9s %10.4f s   %s atom-steps/s%s%s\n' "$ter_how" "$ter_t" "$(rate "$ter_t")" "$(user)" "$tag"
        if [[ -z "$ter_best" ]] || awk -v a="$ter_t" -v b="$ter_best" 'BEGIN { exit !(a < b) }'; then
            ter_best=$ter_t
            cp "$work/terrace.log" "$work/terrace_best.log"
            [[ ! -f "$work/lj_bench.summary.json" ]] || cp "$work/lj_bench.summary.json" "$work/terrace_best.summary.json"
        fi
    fi
done

if [[ "$repeat" -gt 1 ]]; then
    echo
    if [[ -n "$lmp_best" ]]; then printf 'LAMMPS  : best loop time %10.4f s   %s atom-steps/s\n' "$lmp_best" "$(rate "$lmp_best")"; fi
    if [[ -n "$ter_best" ]]; then printf 'Terrace : best %-9s %10.4f s   %s atom-steps/s\n' "$ter_how" "$ter_best" "$(rate "$ter_best")"; fi
fi
if [[ -n "$lmp_best" && -n "$ter_best" ]]; then
    awk -v a="$lmp_best" -v b="$ter_best" 'BEGIN { printf "ratio   : Terrace/LAMMPS = %.3f (atom-steps/s; >1 means Terrace is faster)\n", a / b }'
fi
if [[ -n "$ter_best" ]]; then
    echo
    echo "Terrace phases (best run):"
    if [[ -f "$work/terrace_best.summary.json" ]]; then
        PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary phases "$work/terrace_best.summary.json"
    else
        echo "    (no run summary: a binary that writes none)"
    fi
fi
if [[ "${KEEP:-0}" == 1 ]]; then echo "work dir: $work"; fi
