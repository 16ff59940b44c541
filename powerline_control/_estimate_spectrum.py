"""The spectral innovation test's old private path; it lives in ``estimate/_spectrum.py`` now."""

from .estimate import spectral_test as spectral_test
from .estimate import whitened_psd as whitened_psd
from .estimate import whitening_factor as whitening_factor
