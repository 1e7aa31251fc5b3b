"""Unit conversions at the edges. Inside terradyn everything is SI (m, s, N, Pa, rad)."""
import math

CM = 1.0e-2  #: metres per centimetre
DEG = math.pi / 180.0  #: radians per degree
N_PER_CM3 = 1.0e6  #: (N/m^3) per (N/cm^3): stress-per-depth coefficients
G = 9.81  #: gravitational acceleration, m/s^2
