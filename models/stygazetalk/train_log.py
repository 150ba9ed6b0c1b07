"""Training curves and best-checkpoint selection shared by both StyGazeTalk trainers."""

from __future__ import annotations

from dataclasses import dataclass, field

from torch import nn


@dataclass
class TrainLog:
    """Validation curve; the weights with the lowest validation loss are kept (early-stopping selection)."""

    steps: list[int] = field(default_factory=list)
    train_loss: list[float] = field(default_factory=list)
    val_loss: list[float] = field(default_factory=list)
    best_step: int = 0
    best_val: float = float("inf")
    seconds: float = 0.0
    _best_state: dict | None = field(default=None, repr=False)

    def record(self, step: int, train_loss: float, val_loss: float, module: nn.Module) -> None:
        self.steps.append(step)
        self.train_loss.append(float(train_loss))
        self.val_loss.append(float(val_loss))
        if val_loss < self.best_val:
            self.best_val, self.best_step = float(val_loss), step
            self._best_state = {k: v.detach().clone() for k, v in module.state_dict().items()}

    def restore_best(self, module: nn.Module) -> None:
        if self._best_state is None:
            raise RuntimeError("no validation point was recorded")
        module.load_state_dict(self._best_state)

    def curve(self) -> dict:
        return {"step": self.steps, "train": self.train_loss, "val": self.val_loss}
