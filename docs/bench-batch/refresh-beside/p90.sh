#!/bin/bash
R=$HOME/res
for i in $(seq 1 900); do grep -q "all done" $R/u90.log 2>/dev/null && break; sleep 1; done
cd $HOME/n90 && cp $OLDPWD/.devpack/prof90.py . 2>/dev/null
WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$HOME/n90 timeout 900 python3 prof90.py > $R/prof90.log 2>&1
echo "prof done" >> $R/prof90.log
