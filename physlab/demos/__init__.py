"""Lesson demos: ``params -> Figure`` callbacks and the small computations behind them.

One module per part of physlab: :mod:`physlab.demos.basics` (lessons 01–03).
"""
