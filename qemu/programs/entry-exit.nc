(millac reproduction: from an air cut into a full slot 0.3 in deep in steel, out again into air)
(stock: entry-exit.stock; the tool's front edge meets X0 at centre X-0.25, leaves at centre X3.25)
G20 G90 G17
G0 Z0.1
G0 X-1 Y1.5
G0 Z-0.3
G1 X4.5 F22
G0 Z0.1
M2
