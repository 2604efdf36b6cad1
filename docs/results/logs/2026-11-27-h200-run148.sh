set -u
# Run 148: 16 threads, paired: w = KD right children kept when no thread waited offered again while the left subtree is built, against v = f9a8ba7.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for d in ('v','w'):
    os.makedirs('/tmp/b16/'+d,exist_ok=True)
    open('/tmp/b16/'+d+'/libas.so.0','wb').write(lzma.open('.dev/z/'+d+'/libas.so.0.xz').read())
open('/tmp/b16/loopd','wb').write(lzma.open('.dev/z/loopd.xz').read()); os.chmod('/tmp/b16/loopd',0o755)
"
S=$PWD/.dev/scenes; A=.dev/z/abdl
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
S0=$(date +%s); el(){ echo $(( $(date +%s) - S0 )); }
for a in "staircase2.ply.zst kd:sah 41" "bunny.ply.zst kd:sah 31" "staircase.ply.zst kd:sah 15" "bathroom.drc kd:sah 9" "bunny.ply.zst kd:midcut 31" "bunny.ply.zst bvh:sah 41"; do set -- $a
  timeout 100 $A /tmp/b16/v /tmp/b16/w $S/$1 $2 16 $3
done
date -u; echo "total $(el) s"
