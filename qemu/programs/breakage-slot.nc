(millac, issue 10: a full slot 0.3 in deep in steel at a gentle F8, about 0.4 of F0)
(a broken tooth doubles the next tooth's chip and stays below the overload hold,)
(so the breakage monitor is what stops the cut; stock: entry-exit.stock)
G20 G90 G17
G0 Z0.1
G0 X-0.3 Y1.5
G0 Z-0.3
G1 X1.5 F8
G0 Z0.1
M2
