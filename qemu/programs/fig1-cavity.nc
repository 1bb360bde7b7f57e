(millac demo: roughing the cavity of Fig. 1, Tlusty, Koren and McNeil, "NC and AC for die sinking")
(die blank X0..5 Y0..3 in, top face Z0; cavity X1..4 Y0.8..2.2 with a bottom sloping up towards +X)
(0.5 in 4-flute end mill in steel at 600 rpm; the flat-bottomed start hole at Pt 1 is drilled before)
(feeds are the hopeful ones a programmer would write: adaptive control trims them to F0 where the cut is heavy)
G20 G90 G17
G0 Z0.1
G0 X1.25 Y1.5            (Pt 1, over the drilled hole)
G1 Z-0.6 F10             (into the hole)
G1 X2.25 F11.5           (cut A: full width d, depth hA, Pt 1 -> Pt 2)
G1 Z-0.45 F10
G1 X3.25 F15             (cut b: Pt 2 -> Pt 3, lesser depth, still full width)
G1 Z-0.3 F10
G1 X3.75 F22             (Pt 3 -> Pt 4)
(side cut B: width e = 0.2 in < d/2 around the slot, half circles at the ends)
G1 Y1.3 F22
G1 X1.25
G2 X1.25 Y1.7 I0 J0.2
G1 X3.75
G2 X3.75 Y1.3 I0 J-0.2
(side cut C: the next 0.2 in)
G1 Y1.1
G1 X1.25
G2 X1.25 Y1.9 J0.4
G1 X3.75
G2 X3.75 Y1.1 J-0.4
G0 Z0.1                  (stock f is left for the smaller cutters)
G0 X0 Y0
M2
