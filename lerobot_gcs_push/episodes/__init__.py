"""How episodes run: one rollout of any policy in any registered env (`rollout`), and many of them at once on
local processes or Ray actors (`workers`). Demonstrations, evaluation and active data all run through here."""
