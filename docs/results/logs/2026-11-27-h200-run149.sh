set -u
# Run 149: 16 threads: x = BIH pending right children offered (HEAD) against w = 2dfa2c8, paired; then bench_build at HEAD, the five scenes, per-round times.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for d in ('w','x'):
    os.makedirs('/tmp/b16/'+d,exist_ok=True)
    open('/tmp/b16/'+d+'/libas.so.0','wb').write(lzma.open('.dev/z/'+d+'/libas.so.0.xz').read())
open('/tmp/b16/bench_build','wb').write(lzma.open('.dev/z/bench_build.xz').read()); os.chmod('/tmp/b16/bench_build',0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes; A=.dev/z/abdl
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc); at $(cat .dev/commit)"; lscpu | grep -E "Model name"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
for a in "staircase2.ply.zst bih:bih 81" "bunny.ply.zst bih:bih 61" "staircase.ply.zst bih:bih 31" "bathroom.drc bih:bih 21"; do set -- $a
  timeout 100 $A /tmp/b16/w /tmp/b16/x $S/$1 $2 16 $3
done
BENCH_ROUNDS=1 timeout 400 /tmp/b16/bench_build --runs 5 --paired 15 --commit $(cat .dev/commit) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "triangles\)?$|met|MISS" $OUT/bench-16t.log
date -u; echo "total $(el) s"
