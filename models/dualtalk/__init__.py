"""DualTalk (Peng et al., CVPR 2025): dyadic 3D talking/listening head generation, the released architecture.

Modules: :mod:`.config` (sizes), :mod:`.model` (network), :mod:`.speech` (waveform normalisation, frame
count, log-mel input), :mod:`.official` (loading the released ``DualTalk.pth``), :mod:`.runtime` (offline and
progressive-context streaming adapters), :mod:`.registry` (``dualtalk``, ``dualtalk-offline``),
:mod:`.data` / :mod:`.train` / :mod:`.cli` (``dyadbench train dualtalk``).
"""
