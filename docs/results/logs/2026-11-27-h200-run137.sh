set -u
# Run 137: thread scaling of binned SAH, BIH and grid (lthr), then bench_build at HEAD, 16 threads, the five benchmark scenes.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b16',exist_ok=True)
for n in ('bench_build','loopf','lthr'):
    open('/tmp/b16/'+n,'wb').write(lzma.open('.dev/z/'+n+'.xz').read()); os.chmod('/tmp/b16/'+n,0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc); at $(cat .dev/commit)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
for sc in staircase2.ply.zst bunny.ply.zst bathroom.drc; do
  timeout 90 /tmp/b16/lthr $S/$sc 11 bvh:sah bih:bih grid:grid kd:sah -- 1 2 4 8 16
done
echo "lthr done at $(el) s"
timeout 420 /tmp/b16/bench_build --runs 5 --paired 15 --commit $(cat .dev/commit) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $? at $(el) s"
grep -E "triangles\)?$|met|MISS" $OUT/bench-16t.log
date -u; echo "total $(el) s"
