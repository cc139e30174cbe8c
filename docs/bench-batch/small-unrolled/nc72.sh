#!/bin/bash
# ncu on one P^-1's panel levels (256 Diamonds)
R=$HOME/res; cd $HOME/n72
WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n72 timeout 580 /usr/local/cuda/bin/ncu --profile-from-start off --kernel-name regex:factor_panel --launch-count 32 --section SpeedOfLight --section Occupancy --section LaunchStats --section WarpStateStats --section MemoryWorkloadAnalysis --section SchedulerStats --csv --page details python3 $HOME/devpack/nc72.py 256 > $R/ncu72.csv 2> $R/ncu72.err
echo "ncu done $?" >> $R/u73.log
