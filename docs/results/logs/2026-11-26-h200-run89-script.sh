set -u
# Run 89: fresh 16-thread run of every variant at 517bbdc (bench_build), the five scenes of the
# 2-core run.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
os.makedirs('/tmp/b',exist_ok=True)
d='/tmp/b/bench_build'; open(d,'wb').write(lzma.open('.dev/z5/bench_build.xz').read()); os.chmod(d,0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
mkdir -p $OUT
timeout 400 /tmp/b/bench_build --runs 5 --commit 517bbdc --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1
grep -E "triangles$|met|MISS|Embree" $OUT/bench-16t.log
date -u
