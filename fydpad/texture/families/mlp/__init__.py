"""The network families: the 3-10-1 MLP of Lin 2016 (model, training, render)."""
