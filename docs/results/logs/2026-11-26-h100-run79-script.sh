set -u
# Grid, BIH and binned SAH on the 16-core GPU host: 12818fc (bench_build) against 9332f03
# (bench_build_old, this session's start), 16 threads, two interleaved rounds.
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
for r in 1 2; do for v in bench_build_old bench_build; do for o in "Grid" "BIH" "binned"; do
  timeout 100 $B/$v --runs 5 --threads 16 --only "$o" $S/bunny.drc $S/staircase.ply.zst $S/bathroom.drc $S/bmw-m6.drc $S/bathroom2.drc $S/chopper-titan.drc 2>&1 | grep -E "^/|Uniform Grid|^BIH|SAH, binned" | sed "s/^/r$r $v /"
done; done; echo "(at $(el) s)"; done
date -u; echo "total $(el) s"
