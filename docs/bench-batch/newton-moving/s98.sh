#!/bin/bash
# session 98: the host's share of the step profiled at 1024 Diamonds (default settings)
export PYTHONUNBUFFERED=1
rm -rf $HOME/n98 && mkdir -p $HOME/n98 && cp -r warpsoft kernels tools scenes pyproject.toml .devpack $HOME/n98/ && ln -sfn ../kernels $HOME/n98/warpsoft/kernels
R=$HOME/res; mkdir -p $R
for i in $(seq 1 300); do [ -f $HOME/mesh1024/ready ] && break; sleep 1; done
nvidia-smi --query-gpu=name,clocks.sm,clocks.mem --format=csv >> $R/u98.log; nproc >> $R/u98.log
(cd $HOME/n98 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n98 timeout 1200 python3 .devpack/prof98.py > $R/prof98.log 2>&1)
echo "prof done" >> $R/u98.log
