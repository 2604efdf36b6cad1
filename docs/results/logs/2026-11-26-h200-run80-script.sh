set -u
# Binned SAH and Embree medium against the thread count on the 16-core GPU host (bench_build at
# 12818fc; the binned builder is the code of 9332f03), and where a 16-thread bunny build spends
# its time when perf is there.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,glob,os
os.makedirs('/tmp/b',exist_ok=True)
for f in glob.glob('.dev/z5/bench_build.xz'):
    d='/tmp/b/'+os.path.basename(f)[:-3]; open(d,'wb').write(lzma.open(f).read()); os.chmod(d,0o755)
open('.dev/lib/libembree3.so.3','wb').write(lzma.open('.dev/embree.xz').read())
"
B=/tmp/b; S=$PWD/.dev/scenes
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for T in 1 2 4 8 16; do
  $B/bench_build --runs 7 --threads $T --only "binned" $S/bunny.drc $S/staircase.ply.zst 2>&1 | grep -E "^/|SAH, binned|Embree 3 medium" | sed "s/^/T$T /"
done
if command -v perf >/dev/null; then
  perf record -g -o /tmp/p.data $B/bench_build --runs 40 --threads 16 --only "binned" $S/bunny.drc > /dev/null 2>&1
  perf report -i /tmp/p.data --no-children --percent-limit 1 --stdio 2>/dev/null | grep -E "^ +[0-9]" | head -30
else
  echo "no perf on this host"
fi
date -u
