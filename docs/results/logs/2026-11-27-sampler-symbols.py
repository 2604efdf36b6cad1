import sys,subprocess,collections,os
# sym.py SAMPLES LIBDIR: symbolize samples in libas.so.0 (local copy at LIBDIR) with addr2line
f=sys.argv[1]; lib=sys.argv[2]
maps=[];S=[]
for l in open(f):
    if l.startswith('M '):
        p=l[2:].split()
        a,b=[int(x,16) for x in p[0].split('-')]; off=int(p[2],16); path=p[5] if len(p)>5 else ''
        maps.append((a,b,off,p[1],path))
    else:
        _,pc,tid=l.split(); S.append((int(pc,16),int(tid)))
def where(pc):
    for a,b,off,perm,path in maps:
        if a<=pc<b: return path,pc-a+off
    return '?',pc
cnt=collections.Counter(); per={}
addrs=collections.defaultdict(list)
for pc,tid in S:
    path,o=where(pc); base=os.path.basename(path)
    if base.startswith('libas.so'): addrs[o].append(tid)
    else: cnt[base or '?']+=1
# symbolize libas offsets (file offset == vaddr for text in typical shared libs approx; use nm ranges)
nm=subprocess.run(['nm','-n','--defined-only',lib],capture_output=True,text=True).stdout.split('\n')
syms=[]
for l in nm:
    p=l.split()
    if len(p)>=3 and p[1] in 'tTwW': syms.append((int(p[0],16),p[2]))
import bisect
keys=[s[0] for s in syms]
for o,t in addrs.items():
    i=bisect.bisect_right(keys,o)-1
    cnt['as:'+(syms[i][1] if i>=0 else '?')]+=len(t)
tot=sum(cnt.values())
print('samples',tot,'threads',len(set(t for _,t in S)))
for k,v in cnt.most_common(int(sys.argv[3]) if len(sys.argv)>3 else 30): print('%6.2f%% %s'%(100*v/tot,k))
