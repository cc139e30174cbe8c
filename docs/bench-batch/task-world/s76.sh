#!/bin/bash
# after s75: the robots again, old first, alternated twice
R=$HOME/res
for i in $(seq 1 900); do grep -q "all done" $R/u75.log 2>/dev/null && break; sleep 1; done
b() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$2 timeout 600 python3 tools/bench.py --device cuda --steps 40 --warmup 10 --scenes finger diamond_inverse 2>&1 | grep -E "median|Error" | grep -v "^|" | sed "s/^/$1 /" >> $R/u76.log); }
b old2 $HOME/o75; b new2 $HOME/n75; b old3 $HOME/o75; b new3 $HOME/n75
echo "robots2 done" >> $R/u76.log
