(millac reproduction: depth-step slot after Ulsoy, Koren and Lauderbaugh 1983, Figs. 2-3)
(stock: depth-step.stock; full-width slot, 0.5 in 4-flute end mill, steel, 600 rpm)
(depth 1 mm for tool centre X 0..1.75, 2 mm for 1.75..3.75, 3 mm for 3.75..5.75 in)
G20 G90 G17
G0 Z0.1
G0 X0 Y1.5
G0 Z-0.1181              (into the start hole: 3 mm below the top of the 3 mm section)
G1 X0.3 F8               (conservative entry from the hole into the 1 mm section)
G1 X5.75 F30             (F30 = f_max: the AC sets the feed)
G0 Z0.1
M2
