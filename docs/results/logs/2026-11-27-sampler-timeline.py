import sys,subprocess,collections,os,bisect
f=sys.argv[1]; lib=sys.argv[2]; start=int(sys.argv[3]); nb=int(sys.argv[4]); W=int(sys.argv[5]) if len(sys.argv)>5 else 160
maps=[];S=[]
for l in open(f):
    if l.startswith('M '):
        p=l[2:].split(); a,b=[int(x,16) for x in p[0].split('-')]; maps.append((a,b,int(p[2],16),p[5] if len(p)>5 else ''))
    else:
        _,pc,tid=l.split(); S.append((int(pc,16),int(tid)))
nm=subprocess.run(['nm','-n','--defined-only',lib],capture_output=True,text=True).stdout.split('\n')
syms=[(int(p[0],16),p[2]) for p in (l.split() for l in nm) if len(p)>=3 and p[1] in 'tTwW']; keys=[s[0] for s in syms]
def name(pc):
    for a,b,off,path in maps:
        if a<=pc<b:
            base=os.path.basename(path)
            if base.startswith('libas.so'):
                i=bisect.bisect_right(keys,pc-a+off)-1; return syms[i][1]
            return base
    return '?'
for k in range(nb):
    chunk=S[start+k*W:start+(k+1)*W]
    c=collections.Counter(name(pc) for pc,_ in chunk)
    busy=sum(v for n,v in c.items() if not n.startswith('libc') and not n.startswith('ld-'))
    top=', '.join('%s %d'%(n,v) for n,v in c.most_common(4))
    print('%5d busy %3d%% | %s'%(start+k*W, 100*busy//max(1,len(chunk)), top))
