(millac benchmark: a pocket after Fig. 5.8 of Munasinghe 1994: walls first, then the island)
(pocket X1..3 Y0.75..2.25 in, 0.25 in = 6.35 mm deep, in steel; 0.5 in 4-flute end mill, 600 rpm)
(stock: pocket.stock, with a start hole drilled at the first corner)
G20 G90 G17
G0 Z0.1
G0 X1.25 Y1.0
G1 Z-0.25 F10            (into the drilled hole)
G1 X1.4 F15              (conservative entry, as in the thesis)
G1 X2.75 F30             (walls: full slot along the pocket's inside)
G1 Y2.0
G1 X1.25
G1 Y1.15
G1 X1.5 Y1.5 F15         (into the cleared band, then the island at a conservative entry feed)
G1 X1.65 F15
G1 X2.5 F30              (island: one full-width pass)
G0 Z0.1
G0 X0 Y0
M2
