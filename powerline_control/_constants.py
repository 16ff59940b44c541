"""Physical constants and shared defaults, each once, with its source.

Every module that needs one imports it from here, so a value cannot differ between two stages
(gravity was 9.81 in one module and 9.80665 in another before this home existed).
"""

#: Standard gravity, m/s^2 (CGPM 1901; the weight per metre m g of a conductor).
GRAVITY = 9.80665
#: Density of air at 15 degC and sea level, kg/m^3 (ISO 2533 standard atmosphere).
AIR_DENSITY = 1.225
#: Strouhal number of a stranded conductor: PLP's f = 3.26 V/d (mph, inches) is St = 0.185
#: (EPRI Orange Book, ch. 3; domain.md 1).
STROUHAL = 0.185
#: Least sensor noise a Kalman filter assumes, as a fraction of its record's RMS: noise-free data
#: (a simulation with ``noise_fraction = 0``) still needs a well-posed Riccati equation. Its
#: consistency test then measures the model's error against this floor.
NOISE_FLOOR_FRACTION = 1e-4
