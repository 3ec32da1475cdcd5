"""The study that regenerates the paper's tables: experiments and their store, the notebooks' plan, the runner,
validation on training meshes, the comparison of arms, the claims ledger and the README's headline.

The library (everything in :mod:`anseg` outside this folder) never imports it.
"""
