(millac reproduction: the thesis' test TIIM, Munasinghe 1994 Table 5.6, scaled to the plant)
(stock: tiim.stock; full slot 7.62 mm deep, 10.5 mm from tool centre X 2.25 in; steel, 0.5 in cutter)
G20 G90 G17
G0 Z0.2
G0 X0.5 Y1.5
G0 Z-0.3                 (into the start hole: 7.62 mm below the first top)
G1 X0.8 F8               (conservative entry from the hole into the 7.62 mm slot)
G1 X4.5 F30              (F30 = f_max: the AC sets the feed)
G0 Z0.2
M2
