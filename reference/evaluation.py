"""The batched evaluation (``--eval batched``): placeholder."""


def batched_evaluate(hiro, harness):
  raise NotImplementedError
