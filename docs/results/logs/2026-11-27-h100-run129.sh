set -u
# Run 129: 16 threads, paired A/B: c33 (5b41486) vs q1 (pieces of 1,024, SBVH shares down to 1,024), and q1 vs q3 (q1 + threads watch 100 us before sleeping).
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for L in ['c33','q1','q3']:
    os.makedirs('/tmp/'+L,exist_ok=True); open('/tmp/'+L+'/libas.so.0','wb').write(lzma.open('.dev/z21/'+L+'.xz').read())
"
S=$PWD/.dev/scenes; Z=.dev/z21
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for pair in "c33 q1" "q1 q3"; do set -- $pair; A=$1; B=$2; echo "== $A vs $B"
for a in "bunny.ply.zst bvh:sah 41" "bunny.ply.zst bvh:sbvh 21" "bunny.ply.zst kd:sah 21" "staircase.ply.zst bvh:sah 31" "staircase.ply.zst bvh:sbvh 15" "staircase.ply.zst kd:sah 11" "bathroom.drc bvh:sah 21" "bathroom.drc bvh:sbvh 11" "staircase2.ply.zst bvh:sah 41"; do
  set -- $a
  timeout 60 $Z/abdl /tmp/$A /tmp/$B $S/$1 $2 16 $3 | sed 's/.*scenes.//'
done; done
date -u; echo "total $(el) s"
