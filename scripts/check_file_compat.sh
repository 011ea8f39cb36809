#!/usr/bin/env bash
# Two builds of Terrace against each other (OLD: e.g. main before a change to the file layers; NEW:
# this checkout's build), each reading what the other wrote:
#  - checkpoints: an OLD run stopped at its first safe point (walltime_limit) is continued by the
#    OLD and by the NEW binary: thermo CSV and final atoms byte for byte, trajectory by h5diff;
#    the NEW checkpoint has the OLD one's contents (h5diff) and the OLD binary continues from it
#    identically (LJ liquid Verlet on 4 ranks, 147-atom energy stepping on 1 and 4 ranks);
#  - read_h5md: frames 3 and -1 of an OLD trajectory, and the same file with a time-independent
#    box/edges (earlier Terrace files), start identical runs (2 ranks);
#  - terrace-analyze (rdf, sq, msd, vdos) on an OLD trajectory of the Rahman argon liquid writes
#    identical CSV files on 1 and 3 ranks;
#  - fixed runs give byte-identical thermo files on 1 and 4 ranks (LJ liquid Verlet 1000 steps,
#    147-atom energy stepping, Cu EAM Verlet and energy stepping).
# Usage: scripts/check_file_compat.sh OLD_BUILD_DIR NEW_BUILD_DIR WORK_DIR   (prints ok/FAIL lines;
# exit status 1 on any FAIL). Takes a few minutes on two cores.
set -uo pipefail
[[ $# -eq 3 ]] || { echo "usage: $0 OLD_BUILD_DIR NEW_BUILD_DIR WORK_DIR" >&2; exit 2; }
OLD=$(realpath "$1"); NEW=$(realpath "$2"); W=$(realpath -m "$3")
REPO="$(cd "$(dirname "${BASH_SOURCE[0]}")/.." && pwd)"
export OMPI_ALLOW_RUN_AS_ROOT=1 OMPI_ALLOW_RUN_AS_ROOT_CONFIRM=1
rm -rf "$W"; mkdir -p "$W"; cd "$W"
fail=0
check() { if cmp -s "$1" "$2"; then echo "ok   $3"; else echo "FAIL $3 ($1 vs $2)"; fail=1; fi; }
run() { local bin=$1 np=$2 deck=$3; if [[ $np == 1 ]]; then $bin $deck > ${deck%.nml}.log 2>&1; else mpirun --oversubscribe -np $np $bin $deck > ${deck%.nml}.log 2>&1; fi; echo $?; }

for case in "lj ckpt_lj.nml 4" "es ckpt_es_ico147.nml 1" "es4 ckpt_es_ico147.nml 4"; do
  set -- $case; name=$1; deck=$2; np=$3
  mkdir -p $name/writer; cd $name/writer
  sed "s#@REPO@#$REPO#; s/&run /\&run walltime_limit=1e-6, /" $REPO/tests/regression/decks/$deck > stop.nml
  rc=$(run $OLD/terrace $np stop.nml); echo "$name: OLD run stopped with status $rc (3 = checkpoint written)"
  cd ..
  for who in old new; do
    for dir in ${who}_from_old; do
      cp -r writer $dir; cd $dir
      sed "s#@REPO@#$REPO#; s/&system /\&system read_checkpoint='restart.h5', /" $REPO/tests/regression/decks/$deck > cont.nml
      bin=$OLD/terrace; [[ $who == new ]] && bin=$NEW/terrace
      rc=$(run $bin $np cont.nml); [[ $rc == 0 ]] || { echo "FAIL $name: $who restart from OLD checkpoint: status $rc"; tail -2 cont.log; fail=1; }
      cd ..
    done
  done
  check old_from_old/thermo.csv new_from_old/thermo.csv "$name np$np: thermo after NEW restart from OLD checkpoint = OLD restart"
  check old_from_old/final.txt new_from_old/final.txt "$name np$np: final atoms after NEW restart from OLD checkpoint = OLD restart"
  h5diff old_from_old/traj.h5 new_from_old/traj.h5 > /dev/null 2>&1 && echo "ok   $name np$np: trajectory (h5diff) identical" || { echo "FAIL $name: trajectory differs"; fail=1; }
  # reverse: a NEW checkpoint read by the OLD binary
  mkdir -p nwriter; cd nwriter
  sed "s#@REPO@#$REPO#; s/&run /\&run walltime_limit=1e-6, /" $REPO/tests/regression/decks/$deck > stop.nml
  rc=$(run $NEW/terrace $np stop.nml); echo "$name: NEW run stopped with status $rc"
  cd ..
  check writer/thermo.csv nwriter/thermo.csv "$name np$np: thermo up to the checkpoint, OLD vs NEW writer"
  h5diff writer/restart.h5 nwriter/restart.h5 > /dev/null 2>&1 && echo "ok   $name np$np: checkpoint file contents identical (h5diff, OLD vs NEW writer)" || { echo "FAIL $name: checkpoints differ (h5diff)"; h5diff writer/restart.h5 nwriter/restart.h5 | head -5; fail=1; }
  cp -r nwriter old_from_new; cd old_from_new
  sed "s#@REPO@#$REPO#; s/&system /\&system read_checkpoint='restart.h5', /" $REPO/tests/regression/decks/$deck > cont.nml
  rc=$(run $OLD/terrace $np cont.nml); [[ $rc == 0 ]] || { echo "FAIL $name: OLD restart from NEW checkpoint: $rc"; fail=1; }
  cd ..
  check old_from_old/thermo.csv old_from_new/thermo.csv "$name np$np: OLD restart from a NEW checkpoint = from an OLD one"
  cd $W
done

# read_h5md from an OLD trajectory (the LJ run's, full length) on 2 ranks, OLD vs NEW
mkdir -p h5 && cd h5
cp $W/lj/old_from_old/traj.h5 old.h5
for who in old new; do
  bin=$OLD/terrace; [[ $who == new ]] && bin=$NEW/terrace
  for fr in 3 -1; do
  cat > start_${who}_$fr.nml <<NML
&run units='lj', dimension=3, n_steps=60, seed=1 /
&system read_h5md='old.h5', h5md_frame=$fr, periodic=.true.,.true.,.true., mass=1.0 /
&potential style='lj', epsilon=1.0, sigma=1.0, cutoff=2.5 /
&integrator style='velocity_verlet', dt=0.005 /
&neighbor skin=0.3 /
&output thermo_every=10, thermo_file='start_${who}_$fr.csv' /
NML
  rc=$(run $bin 2 start_${who}_$fr.nml); [[ $rc == 0 ]] || { echo "FAIL read_h5md $who frame $fr: $rc"; tail -2 start_${who}_$fr.log; fail=1; }
  done
done
for fr in 3 -1; do check start_old_$fr.csv start_new_$fr.csv "read_h5md frame $fr of an OLD trajectory: thermo NEW = OLD (2 ranks)"; done
# the same from an earlier-style file with a time-independent box/edges
/usr/bin/python3 - <<'PY'
import shutil, h5py
shutil.copy("old.h5", "fixed.h5")
with h5py.File("fixed.h5", "r+") as f:
    box = f["particles/all/box"]; e = box["edges/value"][0]; del box["edges"]; box["edges"] = e
PY
for who in old new; do
  bin=$OLD/terrace; [[ $who == new ]] && bin=$NEW/terrace
  sed "s/old.h5/fixed.h5/; s/start_${who}_3.csv/fixed_${who}.csv/" start_${who}_3.nml > fixed_${who}.nml
  rc=$(run $bin 2 fixed_${who}.nml)
done
check fixed_old.csv fixed_new.csv "read_h5md from a fixed box/edges file: NEW = OLD"
# terrace-analyze on an OLD trajectory (the analyze_argon_liquid deck run by the OLD binary), OLD vs NEW
mkdir -p $W/ana && cd $W/ana
sed "s/overwrite=.true./overwrite=.true./" $REPO/tests/regression/decks/argon_liquid_traj.nml > argon.nml
mpirun --oversubscribe -np 2 $OLD/terrace argon.nml > argon.log 2>&1 || { echo "FAIL: OLD argon run"; fail=1; }
for who in old new; do
  bin=$OLD/terrace-analyze; [[ $who == new ]] && bin=$NEW/terrace-analyze
  for np in 1 3; do
    sed "s/output_prefix *= *'[^']*'/output_prefix='a_${who}_np$np'/" $REPO/tests/regression/analysis/argon_liquid.nml > an_${who}_np$np.nml
    mpirun --oversubscribe -np $np $bin an_${who}_np$np.nml --trajectory_file=argon.h5 --output_prefix=a_${who}_np$np > an_${who}_np$np.log 2>&1 || { echo "FAIL analyze $who np$np"; tail -3 an_${who}_np$np.log; fail=1; }
  done
done
for np in 1 3; do for f in a_old_np${np}_*.csv; do check $f ${f/a_old_/a_new_} "terrace-analyze on an OLD trajectory, $np rank(s): ${f#a_old_np${np}_} NEW = OLD"; done; done
# fixed runs, OLD vs NEW thermo byte for byte
mkdir -p $W/runs && cd $W/runs
for spec in "liquid_2048.nml n_steps=1000" "es_ico147.nml -" "eam_cu_4000.nml -" "es_cu_eam_short.nml -"; do
  set -- $spec; deck=$1; len=$2
  for np in 1 4; do
    for who in old new; do
      bin=$OLD/terrace; [[ $who == new ]] && bin=$NEW/terrace
      d=${deck%.nml}_np${np}_$who; mkdir -p $d; cd $d
      sed "s#@REPO@#$REPO#" $REPO/tests/regression/decks/$deck > run.nml
      [[ $len != - ]] && sed -i -E "s/\b(n_steps|run_time) *= *[0-9.eE+-]+/$len/" run.nml
      rc=$(run $bin $np run.nml); [[ $rc == 0 ]] || { echo "FAIL $d: status $rc"; fail=1; }
      cd ..
    done
    check ${deck%.nml}_np${np}_old/thermo.csv ${deck%.nml}_np${np}_new/thermo.csv "run ${deck%.nml} ($len) on $np rank(s): thermo NEW = OLD byte for byte"
  done
done
echo "compat: $([[ $fail == 0 ]] && echo ALL OK || echo FAILURES)"
exit $fail
