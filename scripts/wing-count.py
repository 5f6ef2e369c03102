#!/usr/bin/env python3
"""Counts the station's mover wing: named constants, ifs, boolean joins and lines of
production code, before the rewrite (2ea5205) and today. Run from the repository root:
`python3 scripts/wing-count.py` (docs/results.md#the-wing-counted)."""
import re,subprocess,sys
def prod(text):
    m=re.search(r'#\[cfg\(test\)\]\s*mod tests', text)
    return text[:m.start()] if m else text
def stats(text):
    t=prod(text)
    lines=[l for l in t.split('\n') if l.strip() and not l.strip().startswith('//')]
    code='\n'.join(lines)
    return (len(re.findall(r'^\s*(?:pub(?:\([a-z]+\))? )?const [A-Z_][A-Z0-9_]*\s*:', t, re.M)),
            len(re.findall(r'\bif\b', code)), len(re.findall(r'&&|\|\|', code)), len(lines))
def show(name, files, get):
    tot=[0,0,0,0]
    for f in files:
        s=stats(get(f))
        tot=[a+b for a,b in zip(tot,s)]
        print(f"  {f}: const {s[0]}, if {s[1]}, &&/|| {s[2]}, lines {s[3]}")
    print(f"{name}: const {tot[0]}, if {tot[1]}, &&/|| {tot[2]}, lines {tot[3]}")
before=['tracking.rs','station/yielding.rs','station/stepping_back.rs','station/blocking.rs','station/spacing/mod.rs','station/spacing/swing.rs','station/passing.rs','station/order.rs']
show('before (2ea5205)', before, lambda f: subprocess.run(['git','show','2ea5205:host/core/src/'+f],capture_output=True,text=True).stdout)
after=['perception/tracking.rs','station/movers/mod.rs','station/movers/pace.rs','station/movers/prediction.rs','station/movers/lanes.rs','station/movers/oncoming.rs','station/robots/way.rs','station/robots/spacing/mod.rs','station/robots/spacing/swing.rs','station/robots/line_order.rs','station/robots/desk.rs','station/model.rs']
show('after', after, lambda f: open('host/core/src/'+f).read())
