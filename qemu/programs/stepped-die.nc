(millac benchmark, issue 11: a stepped die cavity roughed in one layer at Z-0.35 in)
(stock: stepped-die.stock; terraces at Z0, -0.12 and -0.24 in: 8.9, 5.8 and 2.8 mm deep)
(zig-zag passes along X, 0.4 in apart: the first a full slot, the others 80 % of the cutter)
(one programmed feed for the whole layer, as a cautious programmer writes it)
G20 G90 G17
G0 Z0.1
G0 X0.25 Y0.5
G0 Z-0.35                (into the start hole)
G1 X3.75 F15             (pass 1: 8.9, 5.8, 2.8 mm deep)
G1 Y0.9
G1 X0.25                 (pass 2, back: 2.8, 5.8, 8.9 mm)
G1 Y1.3
G1 X3.75                 (pass 3)
G1 Y1.7
G1 X0.25                 (pass 4)
G1 Y2.1
G1 X3.75                 (pass 5)
G0 Z0.1
M2
