( demonstrator_f500.nc: reciprocating 400 mm stroke at 500 mm/s, 1 s dwell after every stroke )
( The paper's verification run: 'repeated sequences of movement of worktable by linear )
( reciprocating movement of 400 mm with a delay of 1 second', feeds 100..500 mm/s. )
( Source: Verification of prediction method for energy consumption of machine tool feed )
( axes, section 3. Three back-and-forth cycles. F is in mm/min: 500 mm/s = F30000. )
G21 G90 G94 G61
G0 X0
G4 P1
G1 X400 F30000
G4 P1
X0
G4 P1
G1 X400 F30000
G4 P1
X0
G4 P1
G1 X400 F30000
G4 P1
X0
G4 P1
M30
