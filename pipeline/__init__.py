"""pipeline: perception, from serial bytes to classified, predicted obstacles.

Stages: drivers -> Scan -> cluster -> track -> features -> classify -> predict (+ fusion).
"""
