#!/usr/bin/env bash
# Full disk for the small text outputs (thermo, forces and
# final atoms): each output in turn is put on a 64 KiB tmpfs the test mounts and fills, holding the
# previous run's file. On 1 and 3 ranks the run must exit non-zero within the time limit with one
# 'terrace: error:' line naming the file and the &output key, leave no new file on the device, and
# leave the previous file byte-identical. Needs root for the mount; skipped (77) where it fails.
# (Trajectory and checkpoint on a full device: full_disk_hdf5.sh.)
#
# usage: full_disk_small.sh TERRACE_BIN OUTPUT_DIR
set -u
source "$(dirname "$(readlink -f "$0")")/full_disk_common.sh" "$@"
fail=0
for key in thermo_file forces_file final_atoms_file; do
    for np in 1 3; do
        rm -rf "${mnt:?}"/* "$mnt"/.[!.]* 2> /dev/null
        printf 'previous run\n' > "$mnt/previous.out"
        dd if=/dev/zero of="$mnt/filler" bs=1k count=1000 2> /dev/null   # fills the device
        sum_before=$(md5sum < "$mnt/previous.out")
        work=$out/work_${key}_$np
        rm -rf "$work" && mkdir -p "$work"
        outputs="thermo_every=5, thermo_file='thermo.csv', forces_file='forces.txt'"
        outputs=$(echo "$outputs" | sed "s|$key='[^']*'|$key='$mnt/previous.out'|")
        [ "$key" = final_atoms_file ] && outputs="$outputs, final_atoms_file='$mnt/previous.out'"
        cat > "$work/deck.nml" << EOF
&run units='lj', n_steps=20, seed=1 /
&system lattice='fcc', density=0.8442, cells=4,4,4, mass=1.0, temperature=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&output $outputs /
EOF
        if [ "$np" = 1 ]; then
            (cd "$work" && timeout -k 5 60 "$terrace" deck.nml) > "$work/out" 2> "$work/err"
        else
            (cd "$work" && timeout -k 5 60 mpirun --oversubscribe -np "$np" "$terrace" deck.nml) > "$work/out" 2> "$work/err"
        fi
        rc=$?
        msg=$(grep -m1 '^terrace: error' "$work/err")
        nerr=$(grep -c '^terrace: error' "$work/err")
        left=$(cd "$mnt" && ls -A | grep -v -x -e previous.out -e filler | paste -s -d ' ' -)
        why=''
        if [ "$rc" = 0 ] || [ "$rc" = 124 ] || [ "$rc" = 137 ]; then why="exit $rc"
        elif [ "$nerr" != 1 ]; then why="$nerr error lines"
        elif [[ $msg != *"$mnt/previous.out"* || $msg != *"$key"* || $msg != *"&output"* ]]; then why="message: $msg"
        elif [ -n "$left" ]; then why="files left on the device: $left"
        elif [ "$(md5sum < "$mnt/previous.out")" != "$sum_before" ]; then why='the previous file changed'
        fi
        if [ -z "$why" ]; then
            echo "ok    np=$np $key on a full device: exit $rc, $msg"
        else
            echo "FAIL  np=$np $key on a full device: $why"; fail=1
        fi
    done
done
exit $fail
