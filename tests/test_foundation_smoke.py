import numpy as np

import terradyn as td


def test_generic_fit_is_one_at_horizontal_plate_pushed_down():
    ax, az = td.FITS["generic"].alpha(0.0, np.pi / 2)
    assert abs(az / 1e6 - 1.0) < 0.002  # Li 2013: alpha_z(0, pi/2) = 1 N/cm^3 for the generic fit
    assert abs(ax) < 1e-6
