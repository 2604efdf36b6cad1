set -u
# Run 93: at 7e0d5cd (KD clipping once per crossing reference, PLANAR counts from 2n - m): the stiff cases
# on the GPU for every variant, GPU = CPU on four scenes, then every variant's build on all the host's cores.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,glob,os
os.makedirs('/tmp/b',exist_ok=True)
for f in glob.glob('.dev/z6/*.xz'):
    d='/tmp/b/'+os.path.basename(f)[:-3]; open(d,'wb').write(lzma.open(f).read()); os.chmod(d,0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
B=/tmp/b; S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name,driver_version --format=csv,noheader; echo "cores $(nproc); binaries at $(cat .dev/commit6)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for t in test_stiff test_stiff_more; do
echo "== $t on the GPU, every variant (at $(el) s)"
for v in "bvh sah bvh2-child-bounds" "bvh midcut bvh2-child-bounds" "bvh sweep bvh2-child-bounds" "bvh sbvh bvh2-child-bounds" "bvh sah bvh2-own-bounds" "bvh sah cwbvh" "bvh sbvh cwbvh" "kd midcut kd-standard" "kd sah kd-standard" "kd midcut kd-ropes" "kd sah kd-ropes" "bih bih bih" "octree octree octree" "grid grid grid"; do
  timeout 100 $B/$t --gpu $v > /tmp/st.log 2>&1; rc=$?
  echo "$t --gpu $v: exit $rc, $(grep -c '^ok' /tmp/st.log) ok, $(grep -c '^FAIL' /tmp/st.log) FAIL"; grep -E "^FAIL" -B3 /tmp/st.log | head -12
done; done
echo "== GPU = CPU, every layout: bunny, staircase, bathroom, bmw-m6 (at $(el) s)"
timeout 300 $B/test_gpu_agreement scenes/bunny.drc $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > /tmp/ag.log 2>&1; echo "test_gpu_agreement exit $?: $(grep -c ' 0 differ' /tmp/ag.log) sets with 0 differ, $(grep -cE ' [1-9][0-9]* differ' /tmp/ag.log) with differences"
grep -E " [1-9][0-9]* differ|FAIL|failed" /tmp/ag.log | head
echo "== bench_build, every variant, all cores (at $(el) s)"
mkdir -p $OUT
timeout 420 $B/bench_build --runs 5 --commit $(cat .dev/commit6) --out $OUT/bench-16t.md $S/bunny.ply.zst $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc > $OUT/bench-16t.log 2>&1; echo "bench exit $?"
grep -E "triangles$|met|MISS|Embree" $OUT/bench-16t.log
date -u; echo "total $(el) s"
