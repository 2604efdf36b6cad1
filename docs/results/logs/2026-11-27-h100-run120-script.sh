set -u
# Run 120: the grid at 16 threads, eef89c3 (bl3-s17) against 5fae42e (bl3-s19: ranges dealt out,
# closed-form SAH cost, two-term edge tests, pass 1 planned in units), interleaved; then
# bench_build at 5fae42e (z16), 16 threads, paired rounds, the five benchmark scenes.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for f in ('bl3-s17','bl3-s19'):
    open('/tmp/'+f,'wb').write(lzma.open('.dev/z17/'+f+'.xz').read()); os.chmod('/tmp/'+f,0o755)
os.makedirs('/tmp/b16',exist_ok=True)
open('/tmp/b16/bench_build','wb').write(lzma.open('.dev/z16/bench_build.xz').read()); os.chmod('/tmp/b16/bench_build',0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc); bench at $(cat .dev/commit16)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
run() { timeout 100 /tmp/$1 $S/$2 $3 $4 $5 2>&1 | grep -vE "^[0-9 ]+$" | sed 's/\/[^ ]*\.\(drc\|zst\)//; s/cpu\/build.*//; s/(n=[0-9]*)//g'; }
for round in 1 2 3; do
  for s in bunny.ply.zst staircase.ply.zst bathroom.drc bmw-m6.drc; do
    for b in bl3-s17 bl3-s19; do echo -n "$b $s "; run $b $s grid:grid 16 10; done
  done
done
echo "grid A/B done at $(el) s"
mkdir -p $OUT
timeout 470 /tmp/b16/bench_build --runs 5 --paired 15 --commit $(cat .dev/commit16) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "triangles\)$|met|MISS" $OUT/bench-16t.log
date -u; echo "total $(el) s"
