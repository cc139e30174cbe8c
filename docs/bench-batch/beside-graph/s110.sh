#!/bin/bash
# session 106: two more batch runs on the same machine (s109.sh's trees): the new tree (lag 2), then 731d2f7
export PYTHONUNBUFFERED=1
R=$HOME/res
bb() { (cd $2 && WARPSOFT_MESH_CACHE=$HOME/mesh1024 PYTHONPATH=$HOME/dw:$2 timeout 900 python3 tools/batch_bench.py --device cuda --warmup 3 --share-tolerance 0.01 --meshes 1024 --sizes 1024 --preconditioner factors --steps 100 --out $HOME/bb/$1 $3 2>&1 | tee $HOME/bb/full109_$1.log | grep "batch \|Error\|error" | sed "s/^/$1 /" >> $R/u109.log); cp $HOME/bb/$1/batch.json $R/bb109_$1.json; python3 -c "import json;r=json.load(open('$R/bb109_$1.json'))['rows'][0];print('$1', 'mean', round(r['step_mean_ms'],2), 'median', round(r['step_ms'],2), 'graph', round(r['graph_ms'],2), 'refresh', round(r['refresh_ms'],2), 'run/s', round(r['run_design_steps_per_s']), 'cg', sum(r['step_cg_iterations']), 'refreshes', r['world_refreshes'])" >> $R/u109.log; echo "bb $1 done" >> $R/u109.log; }
bb lag2b $HOME/n109 "--world-lag 2"
bb old1 $HOME/o106
echo "all done" >> $R/u109.log
