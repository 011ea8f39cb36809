#!/usr/bin/env bash
# Cost of one neighbour-list rebuild per atom on a small and a large system, counted by callgrind
# (instruction counts repeat exactly on a shared machine): Rahman's liquid argon (864 atoms, the
# liquid input/argon_nvt.nml leaves, run as input/argon_nvt_100ns.nml: skin 1 A, exact list,
# ARGON_PS ps, default 20 = 2000 steps) and the LJ bench scene (input/lj_bench.nml, 32,000 atoms,
# skin 0.3 sigma, LJ_STEPS steps, default 100). Per build and per owned atom: the whole rebuild
# (engine_rebuild: migration, bins, the owned sort, the halo's border exchange, the list, the
# potential's rebuild hook), the list build alone (nl_build), and its parts; per step and atom the
# ghost refresh (domain_forward). Needs a -DTERRACE_PORTABLE=ON build (valgrind stops on AVX-512).
# WALL=N: no callgrind; any build (native too), N alternating rounds of both scenes, and per build
# and atom the run log's Neigh phase (wall time), per step and atom its Comm phase; median and range.
# Both: the ghost shell's volume over the box's, ((L + 2 c)^3 - L^3) / L^3 with c = rc + skin, and
# that of half the images (one rank: the ghosts per owned atom at uniform density; the bins, sort
# and halo work grow with it).
# BRANCHES=1 (callgrind): also callgrind's simulated mispredicted conditional branches per build and
# owned atom in the whole rebuild (--branch-sim=yes: a model of a predictor, not this machine's).
# Usage: [WALL=N] [BRANCHES=1] scripts/bench/list_build_cost.sh TERRACE [TERRACE_2 ...]
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
figure() { PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get "$@"; }
[[ $# -ge 1 ]] || { echo "usage: $0 PORTABLE_TERRACE [MORE ...]" >&2; exit 2; }
wall="${WALL:-0}"; [[ "$wall" =~ ^[0-9]+$ ]] || { echo "list_build_cost: WALL must be a number of rounds" >&2; exit 2; }
if [[ $wall == 0 ]]; then
    for c in valgrind callgrind_annotate; do command -v $c > /dev/null || { echo "list_build_cost: $c not found" >&2; exit 2; }; done
fi
ps="${ARGON_PS:-20}"; nlj="${LJ_STEPS:-100}"
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
bins=(); for b in "$@"; do [[ -x $b ]] || { echo "list_build_cost: $b is not executable" >&2; exit 2; }; bins+=("$(realpath "$b")"); done
cd "$work"
cp "$repo/input/argon_nvt.nml" .
"${bins[0]}" argon_nvt.nml > eq.log 2>&1 || { tail eq.log >&2; exit 1; }     # argon_nvt_eq.atoms
# (the list this script measures: skin 1 A, no outer list)
sed -e "s/run_time=100000.0/run_time=$ps/" -e "s#^&neighbor .*/#\&neighbor skin=1.0 /#" "$repo/input/argon_nvt_100ns.nml" > argon.nml
sed -E "s/n_steps=[0-9]+/n_steps=$nlj/" "$repo/input/lj_bench.nml" > lj.nml
echo "list build cost per atom; $(date -u '+%Y-%m-%d %H:%M UTC'); commit $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "machine: $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1), $(env -u OMP_NUM_THREADS nproc) cores visible, load $(cut -d' ' -f1-3 /proc/loadavg)"
echo "argon: 864 atoms, $ps ps (skin 1 A, exact list); lj: 32,000 atoms, $nlj steps (skin 0.3 sigma, exact list)"
# and the bins of nl_setup_bins on one rank: the box and the ghost shell (L + 2 c) covered by bins c
# wide across (x, y) and c/2 along z, the last ones sticking out; each atom scans a 3 x 3 x 5 stencil of them, half of it
# (the upper half; ghosts at the same z in full), against the half sphere of radius c it needs
/usr/bin/python3 -c "
import math
for name, l, c in (('argon', 34.6809019, 9.5), ('lj', 20 * (4 / 0.8442) ** (1 / 3), 2.8)):
    e = l + 2 * c; wxy = c; wz = c / 2
    print('  %-6s ghost shell / box volume %.3f, %.3f without the slab below in z (Lennard-Jones: domain_t%%ghosts_below)'
          ' (box %.4g, rc + skin c = %.3g); bins %.4g x %.4g x %.4g = %.3f x %.3f x %.3f c;'
          ' stencil / cutoff sphere volume %.2f' % (name, (e ** 3 - l ** 3) / l ** 3, (e ** 3 - l ** 3 - c * e * e) / l ** 3,
                                                     l, c, wxy, wxy, wz, wxy / c, wxy / c, wz / c,
                                                     9 * wxy * wxy * 5 * wz / (4 / 3 * math.pi * c ** 3)))
    # half the images (one rank, &neighbor images = 'auto': terrace_domain's half_images): the 13
    # 'positive' shifts' images within c of the box, 3 faces, 6 edges (quarter cylinders) and 4
    # corners (sphere octants): (3 L^2 c + 6 L pi c^2 / 4 + 4 pi c^3 / 6) / L^3
    print('         half the images (images = \'auto\'): %.3f box volumes' % ((3 * l * l * c + 1.5 * math.pi * l * c * c
                                                                       + 2 * math.pi / 3 * c ** 3) / l ** 3))"
if [[ $wall != 0 ]]; then
    : > wall.txt
    for ((r = 1; r <= wall; r++)); do
        k=0
        for b in "${bins[@]}"; do
            k=$((k + 1))
            for scene in argon lj; do
                rm -f $scene.summary.json argon_nvt_100ns.csv argon_nvt_100ns.h5 argon_nvt_100ns.ckpt.h5
                "$b" $scene.nml > $scene.log 2>&1 || { echo "list_build_cost: $b $scene.nml failed" >&2; tail -3 $scene.log >&2; exit 1; }
                echo "$k $scene $(figure $scene.summary.json run/atoms) $(figure $scene.summary.json neighbor/builds)" \
                     "$(figure $scene.summary.json timing/phases/Neigh/avg_s) $(figure $scene.summary.json timing/phases/Comm/avg_s)" \
                     "$(figure $scene.summary.json timing/steps)" >> wall.txt
            done
        done
    done
    /usr/bin/python3 - wall.txt <<'PY'
import statistics as st, sys
rows = [l.split() for l in open(sys.argv[1])]
print('%-6s %-6s %6s %6s | %-30s | %-30s' % ('build', 'scene', 'atoms', 'builds', 'Neigh ns per build per atom', 'Comm ns per step per atom'))
for key in dict.fromkeys((r[0], r[1]) for r in rows):
    rs = [r for r in rows if (r[0], r[1]) == key]
    n, b, steps = int(rs[0][2]), int(rs[0][3]), int(rs[0][6])
    ne = sorted(1e9 * float(r[4]) / int(r[3]) / n for r in rs)
    co = sorted(1e9 * float(r[5]) / int(r[6]) / n for r in rs)
    print('%-6s %-6s %6d %6d | %7.1f [%7.1f, %7.1f] (%d) | %7.1f [%7.1f, %7.1f]' % (key[0], key[1], n, b, st.median(ne), ne[0], ne[-1],
          len(ne), st.median(co), co[0], co[-1]))
print('median [lowest, highest] over the rounds; binaries:')
PY
    k=0; for b in "${bins[@]}"; do k=$((k + 1)); echo "  $k: $b"; done
    exit 0
fi
branches="${BRANCHES:-0}"
printf '%-6s %-6s %6s | %9s %9s %9s %9s %9s %9s %9s | %9s' build scene builds rebuild nl_build \
    bins sort borders migrate scan 'fwd/step'
[[ $branches == 1 ]] && printf ' | %9s' 'mispred.'
echo
printf '%-6s %-6s %6s | %s | %s\n' '' '' '' 'instructions per build per owned atom (rebuild = all of engine_rebuild)' \
    'ghost refresh per step per owned atom'
k=0
for b in "${bins[@]}"; do
    k=$((k + 1))
    for scene in argon lj; do
        rm -f $scene.summary.json argon_nvt_100ns.csv argon_nvt_100ns.h5 argon_nvt_100ns.ckpt.h5
        sim=(); [[ $branches == 1 ]] && sim=(--branch-sim=yes)
        valgrind --tool=callgrind "${sim[@]}" --callgrind-out-file=cg.$k.$scene "$b" $scene.nml > $scene.$k.log 2> cg.err \
            || { echo "list_build_cost: $b failed under valgrind (a -march=native build? use -DTERRACE_PORTABLE=ON)" >&2; tail -3 cg.err >&2; exit 2; }
        callgrind_annotate --inclusive=yes --threshold=100 cg.$k.$scene > ann.txt 2> /dev/null
        ir() { awk -v pat="$1" '$0 ~ pat { gsub(/,/, "", $1); print $1; exit }' ann.txt; }
        builds=$(figure $scene.summary.json neighbor/builds)
        natoms=$(figure $scene.summary.json run/atoms)
        steps=$(figure $scene.summary.json timing/steps)
        printf '%-6s %-6s %6d | ' "$k" $scene "$builds"
        for f in 'engine_MOD_engine_rebuild ' 'neighbor_list_MOD_nl_build ' 'neighbor_list_MOD_nl_setup_bins ' \
                 'neighbor_list_MOD_nl_sort_owned ' 'domain_MOD_domain_borders ' 'domain_MOD_domain_migrate ' \
                 'neighbor_list_MOD_scan[ .]'; do
            v=$(ir "$f"); printf '%9.1f ' "$(awk -v v="${v:-0}" -v b="$builds" -v n="$natoms" 'BEGIN { print v / b / n }')"
        done
        v=$(ir 'domain_MOD_domain_forward '); printf '| %9.1f' "$(awk -v v="${v:-0}" -v s="${steps:-1}" -v n="$natoms" 'BEGIN { print v / s / n }')"
        if [[ $branches == 1 ]]; then
            callgrind_annotate --inclusive=yes --show=Bcm --sort=Bcm --threshold=100 cg.$k.$scene > ann.txt 2> /dev/null
            v=$(ir 'engine_MOD_engine_rebuild '); printf ' | %9.1f' "$(awk -v v="${v:-0}" -v b="$builds" -v n="$natoms" 'BEGIN { print v / b / n }')"
        fi
        echo
    done
done
echo "builds: rebuilds in the run (with the one before the first step); binaries:"
k=0; for b in "${bins[@]}"; do k=$((k + 1)); echo "  $k: $b"; done
