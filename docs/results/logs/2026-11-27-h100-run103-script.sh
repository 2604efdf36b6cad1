set -u
# Run 103: bench_build at 5b2b127 (paired rounds) on all the host's cores, the five benchmark scenes.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,glob,os
os.makedirs('/tmp/b',exist_ok=True)
for f in glob.glob('.dev/z8/*.xz'):
    d='/tmp/b/'+os.path.basename(f)[:-3]; open(d,'wb').write(lzma.open(f).read()); os.chmod(d,0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
B=/tmp/b; S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; echo "cores $(nproc); binaries at $(cat .dev/commit8)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
mkdir -p $OUT
timeout 540 $B/bench_build --runs 5 --paired 7 --commit $(cat .dev/commit8) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $?"
grep -E "triangles$|met|MISS|Embree" $OUT/bench-16t.log
date -u; echo "total $(el) s"
