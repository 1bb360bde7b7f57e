(millac benchmark, issue 11: the pocket after Fig. 5.8 on a stock that is not as described)
(described: hidden-boss.described.stock, the first wall's band pre-roughed to the pocket depth)
(actual: hidden-boss.actual.stock, a boss left standing in that band: an offline plan made)
(from the description runs into it at the air-cut feed)
G20 G90 G17
G0 Z0.1
G0 X1.25 Y1.0
G1 Z-0.25 F10            (into the drilled hole)
G1 X1.4 F15              (conservative entry, as in the thesis)
G1 X2.75 F30             (walls: along the pre-roughed band first)
G1 Y2.0
G1 X1.25
G1 Y1.15
G1 X1.5 Y1.5 F15         (into the cleared band, then the island at a conservative entry feed)
G1 X1.65 F15
G1 X2.5 F30              (island: one full-width pass)
G0 Z0.1
G0 X0 Y0
M2
