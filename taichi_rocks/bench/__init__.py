"""``taichi-rocks bench``: the measured accuracy-against-cost study, speed against peers, and its report."""
