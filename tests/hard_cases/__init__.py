"""Hard cases (issue 6): each stays numerically stable, with a measured bound per case."""
