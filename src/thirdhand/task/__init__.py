"""The task file ``thirdhand.task/1``: models, validation, atomic load and save.

The public entry point is :mod:`thirdhand.taskfile`.
"""
