( three_axis_contour.nc: small illustrative contour for config/three_axis_mill.yaml )
( A 60 x 40 mm pocket outline with rounded corners in XY, plunging and retracting in Z. )
( Units mm, feeds mm/min. Not from the paper. )
G21 G90 G94 G17 G64
G0 X0 Y0 Z20
G0 X10 Y0
G1 Z-2 F600
G1 X50 Y0 F3000
G3 X60 Y10 I0 J10
G1 X60 Y30
G3 X50 Y40 I-10 J0
G1 X10 Y40
G3 X0 Y30 I0 J-10
G1 X0 Y10
G3 X10 Y0 I10 J0
G1 Z5 F1200
G0 X30 Y20
G1 Z-1 F600
G2 X30 Y20 I10 J0 F2400
G0 Z20
G0 X0 Y0
M30
