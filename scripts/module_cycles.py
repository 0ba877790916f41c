#!/usr/bin/env python3
"""Import circles between the files of a crate (issue 38, item 4).

Usage: python3 scripts/module_cycles.py crates/bevy_shadow_fins/src [-v]

An edge goes from a file to the file of each module it names through a
`crate::`, `super::` or `self::` path (use groups parsed), or through a path
into one of its own child modules (`coverage::prepare` in a mod.rs). The
crate root (lib.rs) is left out: its re-exports are the public API, not a
dependency. A parent mod.rs calling a child that calls `super::helper` back
is a circle too: the helper belongs in a sibling both can use (an inline
test module's `super::` is its own file: no edge). Prints each
strongly connected component of two or more files, then the count; `-v`
also prints every file's edges. Exits 1 when there is a circle.
"""
import os, re, sys
root = sys.argv[1]
files = {}
for d, _, fs in os.walk(root):
    for f in fs:
        if f.endswith('.rs'):
            p = os.path.join(d, f); rel = os.path.relpath(p, root)
            parts = rel[:-3].split(os.sep)
            if parts[-1] in ('mod', 'lib'): parts = parts[:-1]
            files[tuple(parts)] = rel
def strip(src):
    src = re.sub(r'//[^\n]*', '', src)
    src = re.sub(r'/\*.*?\*/', '', src, flags=re.S)
    src = re.sub(r'"(\\.|[^"\\])*"', '""', src)
    return src
def expand(prefix, body):
    # body of a use group: split top-level commas
    out=[]; depth=0; cur=''
    for ch in body:
        if ch=='{': depth+=1
        if ch=='}': depth-=1
        if ch==',' and depth==0: out.append(cur); cur=''
        else: cur+=ch
    out.append(cur)
    res=[]
    for item in out:
        item=item.strip()
        if not item: continue
        m=re.match(r'^([\w:]*?)::\{(.*)\}$', item, re.S)
        if m: res+=expand(prefix+m.group(1).split('::'), m.group(2))
        else: res.append(prefix+item.split(' as ')[0].strip().split('::'))
    return res
def resolve(mod, path):
    # mod: tuple of the file's module path; path: list of segments
    if path[0]=='crate': base=[]; rest=path[1:]
    elif path[0]=='super':
        base=list(mod); rest=path
        while rest and rest[0]=='super': base=base[:-1]; rest=rest[1:]
    elif path[0]=='self': base=list(mod); rest=path[1:]
    else: return None
    # longest prefix that is a file
    best=None
    for i in range(len(rest)+1):
        t=tuple(base+rest[:i])
        if t in files: best=t
    return best
def inline_mods_self(src):
    # Inside an inline `mod tests { … }`, `super::` is the file itself.
    out=[]; last=0
    for m in re.finditer(r'(?m)^\s*(?:pub(?:\([^)]*\))? )?mod \w+\s*\{', src):
        if m.start() < last: continue
        i=m.end(); depth=1
        while depth and i < len(src):
            if src[i]=='{': depth+=1
            elif src[i]=='}': depth-=1
            i+=1
        # One level up is the file itself: `super::x` is `self::x`, `super::super::x` is `super::x`.
        inner=re.sub(r'\bsuper::((?:super::)*)', lambda s: s.group(1) or 'self::', src[m.end():i])
        out.append(src[last:m.end()]); out.append(inner); last=i
    out.append(src[last:])
    return ''.join(out)
# `crate::Name` of a name lib.rs re-exports depends on the file that defines it.
reexports={}
lib=os.path.join(root, 'lib.rs') if os.path.exists(os.path.join(root, 'lib.rs')) else os.path.join(root, 'main.rs')
if os.path.exists(lib):
    lsrc=strip(open(lib).read())
    for m in re.finditer(r'\bpub\s+use\s+((?:crate::|self::)?\w+(?:::\w+)*)(::\{)?', lsrc):
        head=[x for x in m.group(1).split('::') if x not in ('crate','self')]
        if m.group(2):
            i=m.end();depth=1
            while depth:
                if lsrc[i]=='{':depth+=1
                elif lsrc[i]=='}':depth-=1
                i+=1
            items=expand(head, lsrc[m.end():i-1])
        else: items=[head]
        for item in items:
            best=None
            for k in range(len(item)+1):
                if tuple(item[:k]) in files and k>0: best=tuple(item[:k])
            if best: reexports[item[-1]]=best
def via_root(path):
    # `crate::Name` (or `crate::{Name}`): the defining file of a root re-export.
    if len(path)>=2 and path[0]=='crate' and path[1] in reexports: return reexports[path[1]]
    return None
edges={}
for mod, rel in files.items():
    src=inline_mods_self(strip(open(os.path.join(root, rel)).read()))
    paths=[]
    for m in re.finditer(r'\buse\s+((?:crate|super|self)(?:::\w+)*)(?:::\{)?', src):
        start=m.end()
        if src[m.end()-1]=='{':
            depth=1;i=start
            while depth: 
                if src[i]=='{':depth+=1
                elif src[i]=='}':depth-=1
                i+=1
            paths+=expand(m.group(1).split('::'), src[start:i-1])
        else: paths.append(m.group(1).split('::'))
    # Whole paths only: `crate::a::{…}` and `crate::a::*` were read as use groups above.
    for m in re.finditer(r'\b((?:crate|super)(?:::\w+)+)\b(?!::[\w{*])', src):
        paths.append(m.group(1).split('::'))
    # relative paths into this module's children (`coverage::prepare`) and `use child::…`
    kids=[k[-1] for k in files if len(k)==len(mod)+1 and k[:len(mod)]==mod]
    for k in kids:
        for m in re.finditer(r'(?<![:\w])'+k+r'((?:::\w+)+)', src):
            paths.append(['self',k]+m.group(1).split('::')[1:])
        for m in re.finditer(r'\buse\s+'+k+r'::\{', src):
            start=m.end();depth=1;i=start
            while depth:
                if src[i]=='{':depth+=1
                elif src[i]=='}':depth-=1
                i+=1
            paths+=expand(['self',k], src[start:i-1])
    tgt=set()
    for p in paths:
        r=via_root(p) or resolve(mod,p)
        if r is not None and r!=mod and not (len(r)<len(mod) and mod[:len(r)]==r and r==()):
            tgt.add(r)
    # a parent module (mod.rs) declares children: using child from parent is fine; child using parent counted
    edges[mod]=tgt
# strongly connected components (Tarjan)
idx={}; low={}; st=[]; on=set(); sccs=[]; c=[0]
sys.setrecursionlimit(10000)
def sc(v):
    idx[v]=low[v]=c[0]; c[0]+=1; st.append(v); on.add(v)
    for w in edges.get(v,()):
        if w not in idx: sc(w); low[v]=min(low[v],low[w])
        elif w in on: low[v]=min(low[v],idx[w])
    if low[v]==idx[v]:
        comp=[]
        while True:
            w=st.pop(); on.discard(w); comp.append(w)
            if w==v: break
        if len(comp)>1: sccs.append(comp)
for v in files: 
    if v not in idx: sc(v)
name=lambda t: files[t]
if '-v' in sys.argv:
    for m in sorted(edges): print(name(m), '->', ', '.join(sorted(name(t) for t in edges[m])))
for comp in sccs: print('CYCLE:', ' '.join(sorted(name(t) for t in comp)))
print(len(sccs), 'cycles')
sys.exit(1 if sccs else 0)
