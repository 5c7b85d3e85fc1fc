"""No view contains NaN or Inf at any cell: smoothness 0 and 1, metallic 0 and 1, the grazing
silhouette (exact views sample pixel centres right up to n.v = 0), and a Sun at grazing
incidence or below the horizon."""

import numpy as np
import pytest

from addon.params import VIEWS
from conftest import render


@pytest.mark.parametrize("sun", [(-0.3, -0.6, 0.74), (1.0, 0.0, 0.0), (0.0, 0.2, -1.0)],
                         ids=["sun-front", "sun-grazing", "sun-below"])
def test_every_view_is_finite(tmp_path, sun):
    images, _ = render(tmp_path, view=VIEWS, grid=(3, 3), size=48, samples=2,
                       sun_to_light=sun, sun_strength=3.0, env_samples=1)
    for view, img in images.items():
        assert np.isfinite(img).all(), f"view {view} has NaN/Inf with sun {sun}"
        assert (img >= 0).all() or view == "normal", f"view {view} is negative"
