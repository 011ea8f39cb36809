#!/usr/bin/env bash
# Wrapped images against copies (&neighbor images, doc/input.md) on a slice of the 100 ns argon job
# (input/argon_nvt_100ns.nml for PS ps, default 300, from the liquid input/argon_nvt.nml leaves), in
# mixed precision at GROMACS's drift tolerance, built every 40 steps and pruned every 10 (the
# anchors' ar_terrace_mixed_pruned): scripts/bench/phase_ab.sh ROUNDS rounds of one binary run with
# images = 'copies' (binary 0: a wrapper that adds the key to the deck) and as it is, 'auto' (binary
# 1), alternating; per phase the lowest and the median, and the ratio of the medians.
# Usage: scripts/bench/images_ab.sh [ROUNDS [TERRACE [PS]]]   (defaults 9, build/terrace, 300)
set -euo pipefail
here="$(cd "$(dirname "${BASH_SOURCE[0]}")" && pwd)"; repo="$(cd "$here/../.." && pwd)"
rounds="${1:-9}"; terrace="$(realpath "${2:-$repo/build/terrace}")"; ps="${3:-300}"
[[ "$rounds" =~ ^[1-9][0-9]*$ && "$ps" =~ ^[1-9][0-9]*$ && -x "$terrace" ]] \
    || { echo "usage: $0 [ROUNDS [TERRACE [PS]]]" >&2; exit 2; }
work="$(mktemp -d)"; trap 'rm -rf "$work"' EXIT
cd "$work"
cp "$repo/input/argon_nvt.nml" .
"$terrace" argon_nvt.nml > argon_nvt.log 2>&1 || { echo "images_ab: input/argon_nvt.nml failed" >&2; tail argon_nvt.log >&2; exit 1; }
tol_ev="$(python3 -c "print('%.6g' % (0.005 / 96.48533212331))")"    # GROMACS's default, 0.005 kJ/mol/ps
sed -E -e "s/run_time=100000.0/run_time=$ps.0/" -e "s#shift=.true. /#shift=.true., precision='mixed' /#" \
    -e "s#^&neighbor .*/#\&neighbor buffer_tolerance=$tol_ev, every=40, prune_every=10 /#" \
    -e "s#checkpoint_interval=1000.0 /#checkpoint_interval=1000.0, overwrite=.true. /#" \
    "$repo/input/argon_nvt_100ns.nml" > slice.nml
[[ $(grep -c -e "^&run .*run_time=$ps.0" -e "^&potential .*precision='mixed'" -e "^&neighbor .*prune_every=10 /" \
    -e "overwrite=.true. /" slice.nml) == 4 ]] \
    || { echo "images_ab: could not edit the deck" >&2; exit 1; }
cat > copies <<WRAP
#!/usr/bin/env bash
# $terrace with &neighbor images = 'copies' added to the deck (the deck restored afterwards)
cp "\$1" "\$1.orig"
sed -i "s#^&neighbor #\\&neighbor images='copies', #" "\$1"
grep -q "images='copies'" "\$1" || exit 3
"$terrace" "\$@"; rc=\$?
mv "\$1.orig" "\$1"
exit \$rc
WRAP
chmod +x copies
echo "images_ab: $ps ps of the argon job, mixed precision, buffer_tolerance=$tol_ev eV/ps, every=40, prune_every=10;"
echo "  binary 0: images='copies' ($terrace through a wrapper), binary 1: images='auto' (the same binary)"
echo "  commit $(git -C "$repo" rev-parse --short HEAD 2>/dev/null || echo unknown)"
bash "$here/phase_ab.sh" "$rounds" slice.nml ./copies "$terrace"
