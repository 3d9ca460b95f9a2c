"""Pair datasets: real ones (DeepPCB), synthetic flaw patterns and the demo pair, and rendered samples.

- :mod:`rsi.datasets.deeppcb`   the DeepPCB benchmark: loading and checking its files
- :mod:`rsi.datasets.evaluate`  rsi's detector on DeepPCB and its scoring
- :mod:`rsi.datasets.synthetic` textured surfaces, flaw patterns, synthetic pairs with known truth
- :mod:`rsi.datasets.demo`      the demo pair through the camera model (``rsi demo-pair``)
- :mod:`rsi.datasets.rendered`  a simulator vista written as a labelled sample (``rsi sim render``)
"""
