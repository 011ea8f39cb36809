#!/usr/bin/env bash
# terrace-analyze says when the sampling cannot give the asked quantity:
# solid argon (fcc, 80 K) with frames 400 fs apart (Nyquist 1.25 THz, below argon's vibrations)
# must warn that the VDOS is aliased and that the (negative) D is not meaningful; 0.8 ps of frames
# 4 fs apart must warn that the peak lies below the resolution 1/(M dt); 6 ps of frames 10 fs apart
# must not warn about the VDOS.
# usage: analyze_warnings.sh TERRACE TERRACE_ANALYZE OUTDIR
set -u
terrace=$(readlink -f "$1"); analyze=$(readlink -f "$2")
out=$(mkdir -p "$3" && cd "$3" && pwd); cd "$out" && rm -f ./*.h5
deck() {
    cat > "$1.nml" << EOF
&run units='metal', n_steps=$2, seed=3 /
&system lattice='fcc', lattice_constant=5.26, cells=4,4,4, mass=39.948, temperature=80.0 /
&potential style='lj', epsilon=0.0104, sigma=3.4, cutoff=8.5 /
&integrator style='velocity_verlet', dt=0.002 /
&output thermo_every=1000, trajectory_file='$1.h5', trajectory_every=$3, trajectory_fields='position velocity' /
EOF
    "$terrace" "$1.nml" > /dev/null || { echo "FAIL: the run $1 failed"; exit 1; }
}
deck sparse 6000 200
deck short 400 2
deck dense 3000 5
fail=0
"$analyze" --trajectory_file=sparse.h5 --compute=vdos,msd > sparse.log 2>&1
for w in 'VDOS: more than 5 % of the spectrum' 'MSD: D = .* is not a meaningful diffusion coefficient'; do
    if grep -q -E "^terrace: warning: $w" sparse.log; then echo "ok    frames 400 fs apart: $(grep -m1 -E "^terrace: warning: $w" sparse.log | cut -c1-150)"
    else echo "FAIL  frames 400 fs apart: no warning matching '$w'"; fail=1; fi
done
"$analyze" --trajectory_file=short.h5 --compute=vdos > short.log 2>&1
if grep -q '^terrace: warning: VDOS: the highest peak .* lies below the resolution' short.log; then
    echo "ok    0.8 ps of frames: $(grep -m1 'warning: VDOS' short.log | cut -c1-150)"
else echo "FAIL  0.8 ps of frames: no resolution warning"; fail=1; fi
"$analyze" --trajectory_file=dense.h5 --compute=vdos > dense.log 2>&1
if grep -q 'warning: VDOS' dense.log; then echo "FAIL  6 ps of frames 10 fs apart: $(grep 'warning: VDOS' dense.log)"; fail=1
else echo "ok    6 ps of frames 10 fs apart: no VDOS warning ($(grep 'highest peak' dense.log | sed 's/^ *//'))"; fi
exit $fail
