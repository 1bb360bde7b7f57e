(millac example: a round pocket entered on a helix, as CAM ramps into a pocket without a start hole)
(pocket 0.8 in across at X2 Y1.5 in, 0.15 in deep; 0.25 in end mill: tool centre on a 0.275 in radius)
(three helical turns of 0.05 in down, the last two as one line of P2 turns, a full circle at depth)
(to clean the ramp, then out to the wall)
G20 G90 G17
G0 Z0.1
G0 X2.275 Y1.5
G1 Z0 F10
G3 X2.275 Y1.5 Z-0.05 I-0.275 J0 F12
G3 X2.275 Y1.5 Z-0.15 I-0.275 J0 P2
G3 X2.275 Y1.5 I-0.275 J0
G2 X1.725 Y1.5 Z-0.1 R0.275    (a half turn back up, clockwise, in the R form)
G0 Z0.1
G0 X0 Y0
M2
