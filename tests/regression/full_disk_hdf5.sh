#!/usr/bin/env bash
# Full disk for the HDF5 outputs (the trajectory and the
# checkpoint; full_disk_small.sh covers thermo, forces and final atoms). A 64 KiB tmpfs the test
# mounts holds the output, in two ways:
#   full   the device is full before the run (a filler file); a previous checkpoint is there
#   fills  the device is empty: the run writes the first frames / the checkpoint of step 10, and
#          the device fills during the run (a 256-atom checkpoint is 35 KB: the second one and its
#          temporary copy do not fit)
# On 1 and 3 ranks the run must exit non-zero within the time limit (no hang: HDF5 1.10 can leave
# the ranks in different collectives, which Terrace's I/O watchdog ends; TERRACE_IO_WATCHDOG_S=8
# here), print exactly one 'terrace: error' line naming the file and the &output key, no crash
# text, leave no temporary or lock file on the device, leave the previous checkpoint byte-identical
# (full) or the checkpoint of step 10 complete and readable (fills), and leave no trajectory when it
# could not even be created (full). Needs root for the mount; skipped (77) where it fails.
#
# usage: full_disk_hdf5.sh TERRACE_BIN OUTPUT_DIR
set -u
source "$(dirname "$(readlink -f "$0")")/full_disk_common.sh" "$@"
export TERRACE_IO_WATCHDOG_S=8
fail=0
for kind in trajectory checkpoint; do
    for how in full fills; do
        for np in 1 3; do
            rm -rf "${mnt:?}"/* "$mnt"/.[!.]* 2> /dev/null
            if [ "$how" = full ]; then
                printf 'previous checkpoint\n' > "$mnt/c.h5"
                dd if=/dev/zero of="$mnt/filler" bs=1k count=1000 2> /dev/null   # fills the device
            fi
            sum_before=$([ -e "$mnt/c.h5" ] && md5sum < "$mnt/c.h5")
            work=$out/work_${kind}_${how}_$np
            rm -rf "$work" && mkdir -p "$work"
            if [ "$kind" = trajectory ]; then
                o="trajectory_file='$mnt/t.h5', trajectory_every=5"; key=trajectory_file; file=$mnt/t.h5
            else
                o="checkpoint_file='$mnt/c.h5', checkpoint_every=10"; key=checkpoint_file; file=$mnt/c.h5
            fi
            cat > "$work/deck.nml" << EOF
&run units='lj', n_steps=30, seed=1 /
&system lattice='fcc', density=0.8442, cells=4,4,4, mass=1.0, temperature=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&output thermo_every=5, $o /
EOF
            start=$(date +%s)
            if [ "$np" = 1 ]; then
                (cd "$work" && timeout -k 5 60 "$terrace" deck.nml) > "$work/out" 2> "$work/err"
            else
                (cd "$work" && timeout -k 5 60 mpirun --oversubscribe -np "$np" "$terrace" deck.nml) > "$work/out" 2> "$work/err"
            fi
            rc=$?
            secs=$(($(date +%s) - start))
            msg=$(grep -m1 '^terrace: error' "$work/err")
            nerr=$(grep -c '^terrace: error' "$work/err")
            crash=$(cat "$work/out" "$work/err" | grep -m 1 -i -E 'backtrace|SIGSEGV|SIGBUS|SIGABRT|Program received signal|Segmentation fault|core dumped')
            left=$(cd "$mnt" && ls -A | grep -v -x -e c.h5 -e filler -e t.h5 | paste -s -d ' ' -)
            why=''
            if [ "$rc" = 0 ] || [ "$rc" = 124 ] || [ "$rc" = 137 ]; then why="exit $rc"
            elif [ -n "$crash" ]; then why="crash text: $crash"
            elif [ "$nerr" != 1 ]; then why="$nerr error lines"
            elif [[ $msg != *"$file"* || $msg != *"$key"* || $msg != *"&output"* ]]; then why="message: $msg"
            elif [ -n "$left" ]; then why="files left on the device: $left"
            elif [ "$how" = full ] && [ "$(md5sum < "$mnt/c.h5")" != "$sum_before" ]; then why='the previous checkpoint changed'
            elif [ "$how" = full ] && [ -e "$mnt/t.h5" ]; then why='a trajectory that could not be created was left'
            elif [ "$how" = fills ] && [ "$kind" = checkpoint ] && ! /usr/bin/python3 -c "
import h5py, sys
f = h5py.File(sys.argv[1], 'r')
assert f['state'].attrs['step'] == 10 and f['atoms/position'].shape == (256, 3)
assert all(f['atoms'][k].attrs['checksum'] is not None for k in f['atoms'])
" "$mnt/c.h5" 2> /dev/null; then why='the checkpoint of step 10 is not complete and readable'
            fi
            if [ -z "$why" ]; then
                echo "ok    np=$np $kind, device $how: exit $rc after ${secs} s, $msg"
            else
                echo "FAIL  np=$np $kind, device $how: $why"; fail=1
            fi
        done
    done
done
exit $fail
