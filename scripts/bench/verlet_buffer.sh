#!/usr/bin/env bash
# The Verlet buffer from an energy-drift tolerance (&neighbor buffer_tolerance) next to GROMACS's own
# estimate (grompp's "Calculated rlist for 1x1 atom pair-list"), on the anchors' LJ scene in argon
# units (scripts/bench/anchors.sh: 32,000 atoms, fcc at rho* 0.8442, rc 2.5 sigma = 8.5125 A, dt
# 0.005 tau = 0.0107817 ps, T 172.512 K): for each tolerance (kJ/mol/ps per atom) and list interval,
# GROMACS's atom-pair rlist and its 4x4 cluster-list rlist (the one mdrun uses), and Terrace's
# rc + skin (`terrace --check`, metal units: the tolerance in eV/ps). Terrace keeps V'' and V''' at
# the cutoff besides V' (GROMACS: V' only for a plain cut-off) and no cluster-list factor, so its
# figure is the larger; with V' alone the two agree to GROMACS's 0.001 nm step
# (tests/unit/test_verlet_buffer.pf).
# Usage: scripts/bench/verlet_buffer.sh [TERRACE_BINARY]   (needs gmx: Debian package gromacs)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
terrace="$(realpath "${1:-$repo/build/terrace}")"
command -v gmx > /dev/null || { echo "verlet_buffer: gmx not found (as root: apt-get install -y gromacs)" >&2; exit 2; }
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cd "$work"
echo "machine : $(lscpu | sed -n 's/^Model name:[[:space:]]*//p' | head -1), $(date -u '+%Y-%m-%d %H:%M UTC')"
echo "commit  : $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
echo "GROMACS : $(gmx --version 2>&1 | sed -n 's/^GROMACS version: *//p')"
python3 - <<'PY'
sigma, eps_k, mass, kb, n = 0.3405, 119.8, 39.948, 0.00831446261815324, 20
a = sigma * (4 / 0.8442) ** (1 / 3)
basis = [(0, 0, 0), (0.5, 0.5, 0), (0.5, 0, 0.5), (0, 0.5, 0.5)]
with open('lj.gro', 'w') as g:
    g.write('fcc LJ\n%d\n' % (4 * n ** 3))
    k = 0
    for i in range(n):
        for j in range(n):
            for l in range(n):
                for b in basis:
                    k += 1
                    g.write('%5d%-5s%5s%5d%8.3f%8.3f%8.3f\n' % (k % 100000, 'AR', 'AR', k % 100000,
                            (i + b[0]) * a, (j + b[1]) * a, (l + b[2]) * a))
    g.write('%10.5f%10.5f%10.5f\n' % (n * a, n * a, n * a))
with open('lj.top', 'w') as t:
    t.write('[ defaults ]\n1 2 no\n\n[ atomtypes ]\nAR %.3f 0.0 A %.6f %.8f\n\n[ moleculetype ]\nAR 1\n\n'
            '[ atoms ]\n1 AR 1 AR AR 1 0.0 %.3f\n\n[ system ]\nLJ\n\n[ molecules ]\nAR %d\n'
            % (mass, sigma, eps_k * kb, mass, 4 * n ** 3))
open('a.txt', 'w').write('%.6f\n' % (10 * a))
PY
a_ang="$(cat a.txt)"
printf '%-12s %7s %14s %14s %14s\n' 'tolerance' 'nstlist' 'GROMACS 1x1' 'GROMACS 4x4' 'Terrace'
printf '%-12s %7s %14s %14s %14s\n' 'kJ/mol/ps' '' 'rlist nm' 'rlist nm' 'rc+skin nm'
for tol in 0.005 0.0005; do
    for nl in 10 20 40; do
        cat > t.mdp <<EOF2
integrator = md
dt = 0.0107817
nsteps = 0
cutoff-scheme = Verlet
nstlist = $nl
verlet-buffer-tolerance = $tol
coulombtype = Cut-off
rcoulomb = 0.851250
vdwtype = Cut-off
vdw-modifier = Potential-shift
rvdw = 0.851250
tcoupl = no
gen-vel = yes
gen-temp = 172.512
gen-seed = 87287
EOF2
        gmx grompp -f t.mdp -c lj.gro -p lj.top -o t.tpr -maxwarn 10 > grompp.log 2>&1 || { tail -20 grompp.log >&2; exit 1; }
        g1="$(sed -n 's/^Calculated rlist for 1x1 atom pair-list as \([0-9.]*\) nm.*/\1/p' grompp.log)"
        g4="$(sed -n 's/^Set rlist, assuming 4x4 atom pair-list, to \([0-9.]*\) nm.*/\1/p' grompp.log)"
        tol_ev="$(python3 -c "print('%.8g' % ($tol / 96.48533212))")"
        cat > t.nml <<EOF2
&run units='metal', dimension=3, n_steps=10, seed=1 /
&system lattice='fcc', lattice_constant=$a_ang, cells=20,20,20, periodic=.true.,.true.,.true., mass=39.948, temperature=172.512 /
&potential style='lj', epsilon=$(python3 -c "print('%.10g' % (119.8 * 8.617343e-5))"), sigma=3.405, cutoff=8.5125, shift=.true. /
&integrator style='velocity_verlet', dt=0.0107817 /
&neighbor every=$nl, buffer_tolerance=$tol_ev /
&output thermo_every=10 /
EOF2
        "$terrace" --check t.nml > check.log 2>&1 || { tail -5 check.log >&2; exit 1; }
        sk="$(sed -n 's/^ *pairs *: .* + skin \([0-9.eE+-]*\)[,)].*/\1/p' check.log | head -1)"
        printf '%-12s %7d %14s %14s %14.4f\n' "$tol" "$nl" "$g1" "$g4" "$(python3 -c "print((8.5125 + $sk) / 10)")"
    done
done
