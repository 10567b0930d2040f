"""``xted bench``: the paper's Table 1 protocol as a grid of resumable cells. ``config`` (plain
Python) is the grid's settings, ``grid`` enumerates its cells and their fingerprints, ``cells``
computes one kind of cell each, ``store`` keeps their results, ``run`` works through the grid and
``report`` turns stored results into rows and a table."""
