#!/usr/bin/env bash
# The Verlet buffer from an energy-drift tolerance (&neighbor buffer_tolerance) next to GROMACS's own
# estimate (grompp's "Calculated rlist for 1x1 atom pair-list"), on the anchors' LJ scene in argon
# units (scripts/bench/anchors.sh: 32,000 atoms, fcc at rho* 0.8442, rc 2.5 sigma = 8.5125 A, dt
# 0.005 tau = 0.0107817 ps, T 172.512 K): for each tolerance (kJ/mol/ps per atom) and list interval,
# GROMACS's atom-pair rlist and its 4x4 cluster-list rlist (the one mdrun uses), and Terrace's
# rc + skin (the run summary's neighbor/skin of a one-step run, metal units: the tolerance in eV/ps). Terrace keeps V'' and V''' at
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
python3 "$here/lj_gromacs.py" 0                 # lj.gro, lj.top, lj_tol.mdp (the anchors' scene)
a_ang="$(python3 -c "print('%.6f' % (3.405 * (4 / 0.8442) ** (1 / 3)))")"   # its fcc lattice constant, A
printf '%-12s %7s %14s %14s %14s\n' 'tolerance' 'nstlist' 'GROMACS 1x1' 'GROMACS 4x4' 'Terrace'
printf '%-12s %7s %14s %14s %14s\n' 'kJ/mol/ps' '' 'rlist nm' 'rlist nm' 'rc+skin nm'
for tol in 0.005 0.0005; do
    for nl in 10 20 40; do
        sed -E -e "s/^(nstlist +=).*/\1 $nl/" -e "s/^(verlet-buffer-tolerance +=).*/\1 $tol/" lj_tol.mdp > t.mdp
        gmx grompp -f t.mdp -c lj.gro -p lj.top -o t.tpr -maxwarn 10 > grompp.log 2>&1 || { tail -20 grompp.log >&2; exit 1; }
        g1="$(sed -n 's/^Calculated rlist for 1x1 atom pair-list as \([0-9.]*\) nm.*/\1/p' grompp.log)"
        g4="$(sed -n 's/^Set rlist, assuming 4x4 atom pair-list, to \([0-9.]*\) nm.*/\1/p' grompp.log)"
        tol_ev="$(python3 -c "print('%.8g' % ($tol / 96.48533212))")"
        cat > t.nml <<EOF2
&run units='metal', dimension=3, n_steps=1, seed=1 /
&system lattice='fcc', lattice_constant=$a_ang, cells=20,20,20, periodic=.true.,.true.,.true., mass=39.948, temperature=172.512 /
&potential style='lj', epsilon=$(python3 -c "print('%.10g' % (119.8 * 8.617343e-5))"), sigma=3.405, cutoff=8.5125, shift=.true. /
&integrator style='velocity_verlet', dt=0.0107817 /
&neighbor every=$nl, buffer_tolerance=$tol_ev /
&output thermo_every=1 /
EOF2
        "$terrace" t.nml > run.log 2>&1 || { tail -5 run.log >&2; exit 1; }
        sk="$(PYTHONPATH="$repo/scripts${PYTHONPATH:+:$PYTHONPATH}" /usr/bin/python3 -m terrace_tools.summary get t.summary.json neighbor/skin)"
        printf '%-12s %7d %14s %14s %14.4f\n' "$tol" "$nl" "$g1" "$g4" "$(python3 -c "print((8.5125 + $sk) / 10)")"
    done
done
