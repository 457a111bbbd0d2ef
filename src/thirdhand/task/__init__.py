"""The task file ``thirdhand.task/2``: models, validation, atomic load and save.

The public entry point is :mod:`thirdhand.taskfile`.
"""
