set -u
# Run 151: 16 threads, paired: z = a step leaves the count of open steps when its last index is taken (not when a thread finds none left), against x = 2e29872.
export LD_LIBRARY_PATH=$PWD/.dev/lib
python3 -c "
import lzma,os
for d in ('x','z'):
    os.makedirs('/tmp/b16/'+d,exist_ok=True)
    open('/tmp/b16/'+d+'/libas.so.0','wb').write(lzma.open('.dev/z/'+d+'/libas.so.0.xz').read())
"
S=$PWD/.dev/scenes; A=.dev/z/abdl
date -u; nvidia-smi --query-gpu=name --format=csv,noheader; echo "cores $(nproc)"
for a in "bunny.ply.zst bvh:sah 81" "staircase.ply.zst bvh:sah 31" "bathroom.drc bvh:sah 21" "bunny.ply.zst bvh:sbvh 31" "bunny.ply.zst kd:sah 31" "staircase2.ply.zst bih:bih 61"; do set -- $a
  timeout 100 $A /tmp/b16/x /tmp/b16/z $S/$1 $2 16 $3
done
date -u
