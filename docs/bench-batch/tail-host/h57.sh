export PYTHONUNBUFFERED=1
R=$HOME/res
for r in 0 1; do for t in n57 o57; do for s in diamond_inverse finger; do (cd $HOME/$t && WARPSOFT_MESH_CACHE=$HOME/devmesh PYTHONPATH=$HOME/dw:$HOME/$t timeout 300 python3 $HOME/devpack/host1.py $HOME/$t $s 2>&1 | tail -1 >> $R/h57.log); done; done; done
echo "h57 done" >> $R/h57.log
