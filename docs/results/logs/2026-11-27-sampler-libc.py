import sys,subprocess,collections,os,bisect
# libcsym.py SAMPLES LIBC [N]: samples that fall in libc, by dynamic symbol
f=sys.argv[1]; libc=sys.argv[2]
maps=[];S=[]
for l in open(f):
    if l.startswith('M '):
        p=l[2:].split(); a,b=[int(x,16) for x in p[0].split('-')]; maps.append((a,b,int(p[2],16),p[5] if len(p)>5 else ''))
    else:
        _,pc,tid=l.split(); S.append((int(pc,16),int(tid)))
out=subprocess.run(['nm','-D','-n','--defined-only',libc],capture_output=True,text=True).stdout.split('\n')
syms=[(int(p[0],16),p[2]) for p in (l.split() for l in out) if len(p)>=3 and p[1] in 'tTwWi']
keys=[x[0] for x in syms]
c=collections.Counter(); tot=0
for pc,_ in S:
    for a,b,off,path in maps:
        if a<=pc<b:
            if os.path.basename(path).startswith('libc.so'):
                o=pc-a+off; i=bisect.bisect_right(keys,o)-1; c[syms[i][1] if i>=0 else '?']+=1; tot+=1
            break
print('libc samples',tot,'of',len(S))
for k,v in c.most_common(int(sys.argv[3]) if len(sys.argv)>3 else 15): print('%6.2f%% %s'%(100*v/len(S),k))
