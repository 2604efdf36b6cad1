set -u
# Threads kept between builds: bench_build with the thread crew (the commit after d32409d)
# against 9332f03 (bench_build_old), 16 and 4 threads, two interleaved rounds.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,glob,os
os.makedirs('/tmp/b',exist_ok=True)
for f in glob.glob('.dev/z5/bench*.xz'):
    d='/tmp/b/'+os.path.basename(f)[:-3]; open(d,'wb').write(lzma.open(f).read()); os.chmod(d,0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
B=/tmp/b; S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for r in 1 2; do for v in bench_build_old bench_build; do for T in 16 4; do for o in "binned" "SBVH" "KD Standard (SAH)" "BIH" "Grid"; do
  timeout 60 $B/$v --runs 7 --threads $T --only "$o" $S/bunny.drc $S/staircase2.ply.zst $S/staircase.ply.zst $S/bathroom.drc 2>&1 | grep -E "^/|SAH, binned|SBVH|KD Standard|^BIH|Uniform Grid|Embree" | sed "s/^/r$r T$T $v [$o] /"
done; done; done; echo "(at $(el) s)"; done
date -u; echo "total $(el) s"
