### .dev/run107.sh
set -u
# Run 107: bench_build at the BVH thread-threshold and BIH progress commits (z10) and at 5b2b127 (z8),
# 16 threads, paired rounds: the five benchmark scenes with z10, then bunny and staircase2 with z8 as the same host's baseline.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b10',exist_ok=True); os.makedirs('/tmp/b8',exist_ok=True)
for src,d in (('.dev/z10/bench_build.xz','/tmp/b10/bench_build'),('.dev/z8/bench_build.xz','/tmp/b8/bench_build')):
    open(d,'wb').write(lzma.open(src).read()); os.chmod(d,0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; echo "cores $(nproc); new binaries at $(cat .dev/commit10), old at $(cat .dev/commit8)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
timeout 400 /tmp/b10/bench_build --runs 5 --paired 7 --commit $(cat .dev/commit10) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "triangles$|met|MISS" $OUT/bench-16t.log
L=$(( 560 - $(el) ))
timeout $L /tmp/b8/bench_build --runs 5 --paired 7 --commit $(cat .dev/commit8) --out $OUT/bench-16t-old.md $S/bunny.ply.zst $S/staircase2.ply.zst > $OUT/bench-16t-old.log 2>&1; echo "old bench exit $? at $(el) s"
grep -E "triangles$|met|MISS" $OUT/bench-16t-old.log
date -u; echo "total $(el) s"

### .dev/run108.sh
set -u
# Run 108: thread scaling of the binned SAH, BIH and grid builds (bl3-ph: a build loop linked against
# libas at ff619ae with phase timers in the binned SAH and BIH builders), 1-16 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
open('/tmp/bl3','wb').write(lzma.open('.dev/z11/bl3-ph.xz').read()); os.chmod('/tmp/bl3',0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for s in bathroom.drc bmw-m6.drc staircase.ply.zst bunny.ply.zst; do
  for b in bih:default bvh:sah grid:default; do
    for t in 1 2 4 8 16; do
      n=10; [ $t = 1 ] && n=4
      timeout 60 /tmp/bl3 $S/$s $b $t $n 2>&1 | grep -vE "^[0-9 ]+$"
    done
  done
  echo "-- at $(el) s"
  [ $(el) -gt 480 ] && break
done
date -u; echo "total $(el) s"

### .dev/run109.sh
set -u
# Run 109: BIH with the walk and big partitions on every thread (working tree after 0bf729d):
# bl3-ph thread scaling (phase timers in the BIH and binned SAH builders), then bench_build at 16 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b12',exist_ok=True)
for f in ('bench_build','bl3-ph'):
    open('/tmp/b12/'+f,'wb').write(lzma.open('.dev/z12/'+f+'.xz').read()); os.chmod('/tmp/b12/'+f,0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for s in bathroom.drc bmw-m6.drc staircase.ply.zst bunny.ply.zst; do
  for t in 1 4 8 16; do
    n=10; [ $t = 1 ] && n=4
    timeout 60 /tmp/b12/bl3-ph $S/$s bih:default $t $n 2>&1 | grep -vE "^[0-9 ]+$"
  done
  timeout 60 /tmp/b12/bl3-ph $S/$s bvh:sah 16 10 2>&1 | grep -vE "^[0-9 ]+$"
  echo "-- at $(el) s"
done
mkdir -p $OUT
timeout 400 /tmp/b12/bench_build --runs 5 --paired 7 --commit 0bf729d+bih-pieces --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "triangles$|met|MISS" $OUT/bench-16t.log
date -u; echo "total $(el) s"

### .dev/run110.sh
set -u
# Run 110: BIH variants on one host, interleaved: head (0bf729d: the walk on every thread), pieces (+ big
# partitions in pieces), pend (+ pending right children offered to waiting threads), pend1k (+ offered from
# 1,024 objects instead of 4,096); phase timers in the BIH and binned SAH builders.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os,glob
for f in glob.glob('.dev/z13/*.xz'):
    d='/tmp/'+os.path.basename(f)[:-3]; open(d,'wb').write(lzma.open(f).read()); os.chmod(d,0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for round in 1 2; do
for s in bathroom.drc bmw-m6.drc staircase.ply.zst bunny.ply.zst; do
  for t in 4 16; do
    for v in head pieces pend pend1k; do
      echo -n "$v $s t$t: "; timeout 60 /tmp/bl3-$v $S/$s bih:default $t 10 2>&1 | grep -vE "^[0-9 ]+$" | tr '\n' ' ' | sed 's/(n=10)//g; s/sah [0-9.]*//'; echo
    done
  done
  echo -n "binned $s t16: "; timeout 60 /tmp/bl3-head $S/$s bvh:sah 16 10 2>&1 | grep -vE "^[0-9 ]+$" | tr '\n' ' '; echo
  echo "-- at $(el) s"
done
done
date -u; echo "total $(el) s"

### .dev/run111.sh
set -u
# Run 111: bench_build at 1a2be2d (z14), 16 threads, paired rounds, the five benchmark scenes.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b14',exist_ok=True)
open('/tmp/b14/bench_build','wb').write(lzma.open('.dev/z14/bench_build.xz').read()); os.chmod('/tmp/b14/bench_build',0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; echo "cores $(nproc); binaries at $(cat .dev/commit14)"; grep -o -w avx2 /proc/cpuinfo | head -1
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
timeout 500 /tmp/b14/bench_build --runs 5 --paired 15 --commit $(cat .dev/commit14) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "triangles$|met|MISS" $OUT/bench-16t.log
date -u; echo "total $(el) s"

### .dev/run112.sh
set -u
# Run 112: KD SAH phases (bl3-kd: a build loop linked against libas at 60a8532 with phase timers in
# the KD driver: init, root events, tree, emit), 1, 4 and 16 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
open('/tmp/bl3-kd','wb').write(lzma.open('.dev/z15/bl3-kd.xz').read()); os.chmod('/tmp/bl3-kd',0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for s in bunny.ply.zst staircase.ply.zst bathroom.drc bmw-m6.drc; do
  for t in 1 4 16; do
    n=6; [ $t = 1 ] && n=2
    echo -n "$s t$t: "; timeout 100 /tmp/bl3-kd $S/$s kd:sah $t $n 2>&1 | grep -vE "^[0-9 ]+$" | tr '\n' ' ' | sed 's/\/[^ ]*\.\(drc\|zst\)//; s/cpu\/build.*//'; echo
  done
done
date -u

### .dev/run113.sh
set -u
# Run 113: KD SAH phases before (bl3-kd, 60a8532) and after the tree's write on every thread
# (bl3-kd2, working tree), interleaved, 4 and 16 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for f in ('bl3-kd','bl3-kd2'):
    open('/tmp/'+f,'wb').write(lzma.open('.dev/z15/'+f+'.xz').read()); os.chmod('/tmp/'+f,0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for round in 1 2; do
for s in bunny.ply.zst staircase.ply.zst bathroom.drc bmw-m6.drc; do
  for t in 4 16; do
    for b in bl3-kd bl3-kd2; do
      echo -n "$b $s t$t: "; timeout 100 /tmp/$b $S/$s kd:sah $t 5 2>&1 | grep -vE "^[0-9 ]+$" | tr '\n' ' ' | sed 's/\/[^ ]*\.\(drc\|zst\)//; s/cpu\/build.*//; s/(n=5)//g'; echo
    done
  done
done
done
date -u

### .dev/run114.sh
set -u
# Run 114: KD SAH phases with the root lists sorted by a parallel radix sort from 4 threads (bl3-kd3) against
# the tree write on every thread only (bl3-kd2, b88202c), interleaved, 4 and 16 threads.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for f in ('bl3-kd2','bl3-kd3'):
    open('/tmp/'+f,'wb').write(lzma.open('.dev/z15/'+f+'.xz').read()); os.chmod('/tmp/'+f,0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for round in 1 2; do
for s in bunny.ply.zst staircase.ply.zst bathroom.drc bmw-m6.drc; do
  for t in 4 16; do
    for b in bl3-kd2 bl3-kd3; do
      echo -n "$b $s t$t: "; timeout 100 /tmp/$b $S/$s kd:sah $t 5 2>&1 | grep -vE "^[0-9 ]+$" | tr '\n' ' ' | sed 's/\/[^ ]*\.\(drc\|zst\)//; s/cpu\/build.*//; s/(n=5)//g'; echo
    done
  done
done
done
date -u

### .dev/run115.sh
set -u
# Run 115: bench_build at 88a94e9 (z14), 16 threads, paired rounds, the five benchmark scenes.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b14',exist_ok=True)
open('/tmp/b14/bench_build','wb').write(lzma.open('.dev/z14/bench_build.xz').read()); os.chmod('/tmp/b14/bench_build',0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; echo "cores $(nproc); binaries at $(cat .dev/commit14)"; grep -o -w avx2 /proc/cpuinfo | head -1
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
timeout 500 /tmp/b14/bench_build --runs 5 --paired 15 --commit $(cat .dev/commit14) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "triangles$|met|MISS" $OUT/bench-16t.log
date -u; echo "total $(el) s"

### .dev/run116.sh
set -u
# Run 116: BIH with nodes taken in chunks of 64 per task (bl3-bihc) against nodes taken a pair at a
# time from one counter (bl3-kd3, 88a94e9), interleaved, 4 and 16 threads; binned SAH for reference.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for f in ('bl3-kd3','bl3-bihc'):
    open('/tmp/'+f,'wb').write(lzma.open('.dev/z15/'+f+'.xz').read()); os.chmod('/tmp/'+f,0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for round in 1 2; do
for s in bunny.ply.zst staircase.ply.zst bathroom.drc bmw-m6.drc; do
  for t in 4 16; do
    for b in bl3-kd3 bl3-bihc; do
      echo -n "$b $s t$t: "; timeout 100 /tmp/$b $S/$s bih:default $t 10 2>&1 | grep -vE "^[0-9 ]+$" | tr '\n' ' ' | sed 's/\/[^ ]*\.\(drc\|zst\)//; s/cpu\/build.*//; s/(n=10)//g'; echo
    done
  done
  echo -n "binned $s t16: "; timeout 100 /tmp/bl3-kd3 $S/$s bvh:sah 16 10 2>&1 | grep -vE "^[0-9 ]+$" | tr '\n' ' ' | sed 's/\/[^ ]*\.\(drc\|zst\)//; s/cpu\/build.*//; s/(n=10)//g'; echo
done
done
date -u

### .dev/run117.sh
set -u
# Run 117: bench_build at 7de8282 (z14), 16 threads, paired rounds, the five benchmark scenes.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b14',exist_ok=True)
open('/tmp/b14/bench_build','wb').write(lzma.open('.dev/z14/bench_build.xz').read()); os.chmod('/tmp/b14/bench_build',0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; echo "cores $(nproc); binaries at $(cat .dev/commit14)"; grep -o -w avx2 /proc/cpuinfo | head -1
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
timeout 500 /tmp/b14/bench_build --runs 5 --paired 15 --commit $(cat .dev/commit14) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "triangles$|met|MISS" $OUT/bench-16t.log
date -u; echo "total $(el) s"

### .dev/run118.sh
set -u
# Run 118: BIH with big partitions in pieces (bl3-bihp) against 7de8282 (bl3-bihc), interleaved;
# binned SAH for reference.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for f in ('bl3-bihc','bl3-bihp'):
    open('/tmp/'+f,'wb').write(lzma.open('.dev/z15/'+f+'.xz').read()); os.chmod('/tmp/'+f,0o755)
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for round in 1 2; do
for s in bunny.ply.zst staircase.ply.zst bathroom.drc bmw-m6.drc; do
  for t in 4 16; do
    for b in bl3-bihc bl3-bihp; do
      echo -n "$b $s t$t: "; timeout 100 /tmp/$b $S/$s bih:default $t 10 2>&1 | grep -vE "^[0-9 ]+$" | tr '\n' ' ' | sed 's/\/[^ ]*\.\(drc\|zst\)//; s/cpu\/build.*//; s/(n=10)//g'; echo
    done
  done
  echo -n "binned $s t16: "; timeout 100 /tmp/bl3-bihc $S/$s bvh:sah 16 10 2>&1 | grep -vE "^[0-9 ]+$" | tr '\n' ' ' | sed 's/\/[^ ]*\.\(drc\|zst\)//; s/cpu\/build.*//; s/(n=10)//g'; echo
done
done
date -u

