#!/usr/bin/env bash
# Peak memory per atom of the LJ benchmark scene (fcc rho*=0.8442, lj/cut 2.5, skin 0.3) at
# 32,000 atoms (20^3 fcc cells) and 256,000 atoms (40^3 cells), a few steps each, for Terrace
# and, when 'lmp' is installed, LAMMPS (scripts/bench/in.lj_bench).
#
# Usage: scripts/bench/memory.sh [NSTEPS [TERRACE_BINARY]]
#        defaults: NSTEPS=20, TERRACE_BINARY=build/terrace (relative to repo root)
#
# Per size it prints Terrace's own peak memory (the run summary's memory/peak_mib_all_ranks: VmHWM of
# the process, binary, MPI and libraries included) and the peak resident set size (GNU time %M) of both codes; the last line
# is the marginal cost per atom between the two sizes, (peak(256k) - peak(32k)) / 224,000,
# which leaves out the fixed cost of the process.
#
# Environment (optional): LMP (default lmp), TERRACE_LAUNCHER (e.g. "mpirun -np 1"),
# KEEP=1 to keep the work directory.
set -euo pipefail

here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"
repo="$(cd "$here/../.." && pwd)"
# the run summary's figures (scripts/terrace_tools)
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }

nsteps="${1:-20}"
terrace="${2:-$repo/build/terrace}"
LMP="${LMP:-lmp}"

if ! [[ "$nsteps" =~ ^[0-9]+$ ]] || [[ "$nsteps" -eq 0 ]]; then
    echo "usage: $0 [NSTEPS [TERRACE_BINARY]]  (NSTEPS a positive integer)" >&2
    exit 2
fi
if [[ ! -x "$terrace" ]]; then
    echo "Terrace binary '$terrace' not found (build first: scripts/build.sh)" >&2
    exit 2
fi
terrace="$(cd "$(dirname "$terrace")" && pwd)/$(basename "$terrace")"
timebin=/usr/bin/time
if [[ ! -x "$timebin" ]]; then
    echo "GNU time (/usr/bin/time, Debian package 'time') is needed for the peak RSS" >&2
    exit 2
fi

work="$(mktemp -d "${TMPDIR:-/tmp}/lj_memory.XXXXXX")"
if [[ "${KEEP:-0}" != 1 ]]; then
    trap 'rm -rf "$work"' EXIT
fi
export OMP_NUM_THREADS=1
have_lmp=0
if command -v "$LMP" >/dev/null 2>&1; then have_lmp=1; fi

echo "LJ benchmark scene, peak memory, $nsteps steps, 1 rank"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo
printf '%-9s %-8s %-42s %-20s %s\n' atoms code "own report" "peak RSS (KiB)" "RSS bytes/atom"

declare -A rss
for n in 20 40; do
    natoms=$((4 * n * n * n))
    # ---- Terrace
    sed -E -e "s/n_steps=[0-9]+/n_steps=$nsteps/" -e "s/cells=[0-9]+,[0-9]+,[0-9]+/cells=$n,$n,$n/" \
        "$repo/input/lj_bench.nml" > "$work/mem_$n.nml"
    # shellcheck disable=SC2086  # TERRACE_LAUNCHER is deliberately word-split
    (cd "$work" && $timebin -f '%M' -o "terrace_$n.rss" ${TERRACE_LAUNCHER:-} "$terrace" "mem_$n.nml" \
        > "terrace_$n.log" 2>&1) || { echo "Terrace run failed:" >&2; tail -n 20 "$work/terrace_$n.log" >&2; exit 1; }
    own="$(figure "$work/mem_$n.summary.json" memory/peak_mib_all_ranks) MiB, $(figure "$work/mem_$n.summary.json" memory/bytes_per_atom 2> /dev/null || echo '?') bytes/atom"
    got="$(figure "$work/mem_$n.summary.json" timing/atoms 2> /dev/null || true)"
    if [[ "$got" != "$natoms" ]]; then echo "Terrace did not run $natoms atoms (see $work/terrace_$n.log)" >&2; exit 1; fi
    r="$(tail -n 1 "$work/terrace_$n.rss")"
    rss[terrace_$n]=$r
    printf '%-9s %-8s %-42s %-20s %s\n' "$natoms" Terrace "${own:-?}" "$r" \
        "$(awk -v k="$r" -v n="$natoms" 'BEGIN { printf "%.1f", k * 1024 / n }')"
    # ---- LAMMPS
    if [[ $have_lmp == 1 ]]; then
        (cd "$work" && $timebin -f '%M' -o "lammps_$n.rss" "$LMP" -screen none -log "lammps_$n.log" \
            -var nsteps "$nsteps" -var n "$n" -in "$here/in.lj_bench") \
            || { echo "LAMMPS run failed:" >&2; tail -n 20 "$work/lammps_$n.log" >&2; exit 1; }
        own="$(sed -n 's/^Per MPI rank memory allocation (min\/avg\/max) = *[0-9.]* *| *[0-9.]* *| *\([0-9.]*\) Mbytes.*/\1 MiB (LAMMPS estimate)/p' \
            "$work/lammps_$n.log" | tail -n 1)"
        r="$(tail -n 1 "$work/lammps_$n.rss")"
        rss[lammps_$n]=$r
        printf '%-9s %-8s %-42s %-20s %s\n' "$natoms" LAMMPS "${own:-?}" "$r" \
            "$(awk -v k="$r" -v n="$natoms" 'BEGIN { printf "%.1f", k * 1024 / n }')"
    fi
done
echo
for code in terrace lammps; do
    if [[ -n "${rss[${code}_20]:-}" && -n "${rss[${code}_40]:-}" ]]; then
        awk -v a="${rss[${code}_20]}" -v b="${rss[${code}_40]}" -v c="$code" 'BEGIN {
            printf "%-8s marginal: %.1f bytes/atom ((peak RSS at 256,000 - at 32,000) / 224,000)\n",
                   (c == "terrace" ? "Terrace" : "LAMMPS"), (b - a) * 1024 / 224000 }'
    fi
done
if [[ "${KEEP:-0}" == 1 ]]; then echo "work dir: $work"; fi
