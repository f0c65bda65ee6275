# time_vs_error.gp — written by report_cull; run from its own folder:
#   cd docs/report && gnuplot time_vs_error.gp
# draws time_vs_error.svg and time_vs_error.png (the same figure).
$city << EOD
# time_us rate_pct threads label
9.544 97.135 1 "spheres"
17.365 97.135 2 "spheres"
9.825 97.131 1 "+AABB"
17.706 97.131 2 "+AABB"
30.305 97.133 1 ">=1px"
32.038 97.133 2 ">=1px"
30.315 96.976 1 ">=2px"
32.017 96.976 2 ">=2px"
30.305 96.647 1 ">=4px"
31.688 96.647 2 ">=4px"
91.856 66.929 1 "occ 128x64"
81.716 66.929 2 "occ 128x64"
93.504 41.305 1 "occ 256x114"
78.958 41.305 2 "occ 256x114"
104.706 23.400 1 "occ 512x256"
92.858 23.400 2 "occ 512x256"
155.817 15.402 1 "occ 1280x720"
136.754 15.402 2 "occ 1280x720"
5.448 41.305 1 "occ 256x114 kept"
7.441 41.305 2 "occ 256x114 kept"
5.458 15.402 1 "occ 1280x720 kept"
7.220 15.402 2 "occ 1280x720 kept"
EOD
$city_labels << EOD
# label_x label_y text point_x point_y moved
10.2904 102.188 "spheres" 9.544 97.135 1
10.5934 98.815 "+AABB" 9.825 97.131 0
32.6750 102.186 ">=1px" 30.305 97.133 1
32.6858 85.185 ">=2px" 30.315 96.976 1
32.6750 91.594 ">=4px" 30.305 96.647 1
99.0395 68.613 "occ 128x64" 91.856 66.929 0
100.8164 42.989 "occ 256x114" 93.504 41.305 0
112.8945 25.084 "occ 512x256" 104.706 23.400 0
168.0026 17.086 "occ 1280x720" 155.817 15.402 0
5.8741 46.358 "occ 256x114 kept" 5.448 41.305 1
5.8848 20.455 "occ 1280x720 kept" 5.458 15.402 1
EOD
$city_front << EOD
5.448 41.305
5.458 15.402
5490.16 15.402
EOD
$rnd << EOD
# time_us rate_pct threads label
6.511 87.389 1 "spheres"
11.619 87.389 2 "spheres"
6.670 87.350 1 "+AABB"
11.741 87.350 2 "+AABB"
21.137 87.109 1 ">=1px"
21.485 87.109 2 ">=1px"
21.121 86.764 1 ">=2px"
21.529 86.764 2 ">=2px"
21.185 86.311 1 ">=4px"
21.427 86.311 2 ">=4px"
99.390 32.496 1 "occ 128x64"
80.975 32.496 2 "occ 128x64"
93.012 20.092 1 "occ 256x114"
76.305 20.092 2 "occ 256x114"
98.448 11.999 1 "occ 512x256"
83.384 11.999 2 "occ 512x256"
156.862 7.361 1 "occ 1280x720"
129.089 7.361 2 "occ 1280x720"
5.181 20.092 1 "occ 256x114 kept"
7.925 20.092 2 "occ 256x114 kept"
5.447 7.361 1 "occ 1280x720 kept"
7.799 7.361 2 "occ 1280x720 kept"
EOD
$rnd_labels << EOD
# label_x label_y text point_x point_y moved
7.0207 92.442 "spheres" 6.511 87.389 1
7.1916 89.034 "+AABB" 6.670 87.350 0
22.7895 92.162 ">=1px" 21.137 87.109 1
22.7731 88.449 ">=2px" 21.121 86.764 0
22.8414 84.626 ">=4px" 21.185 86.311 0
107.1626 34.180 "occ 128x64" 99.390 32.496 0
100.2859 21.777 "occ 256x114" 93.012 20.092 0
106.1472 13.684 "occ 512x256" 98.448 11.999 0
169.1291 9.046 "occ 1280x720" 156.862 7.361 0
5.5862 25.145 "occ 256x114 kept" 5.181 20.092 1
5.8733 12.415 "occ 1280x720 kept" 5.447 7.361 1
EOD
$rnd_front << EOD
5.181 20.092
5.447 7.361
5490.16 7.361
EOD
set encoding utf8
set logscale x
set xrange [3.6267:549.016]
set yrange [0:105]
set grid xtics mxtics ytics lc rgb '#dddddd'
set xlabel 'time per query, µs (median; log scale)'
set ylabel 'false-visible rate, % of reported entities'
set key top right box opaque
do for [term = 1:2] {
  if (term == 1) { set terminal svg size 1500,650 dynamic font 'DejaVu Sans,12' background '#ffffff'; set output 'time_vs_error.svg'; psz = 1.0 }
  if (term == 2) { set terminal pngcairo size 1500,650 font 'DejaVu Sans,10' background '#ffffff'; set output 'time_vs_error.png'; psz = 1.3 }
  set multiplot layout 1,2 title "Culling: time per query against false-visible rate (truth: exact frustum + 1920x1080 ray caster)\n{/*0.8 machine: 2 cpus, AMD EPYC; 2026-11-27}"
  set title 'city scene walk'
  plot $city_front using 1:2 with steps lw 2 lc rgb '#2ca02c' title 'Pareto front', \
       $city_labels using 1:2:($4 - $1):($6 > 0 ? $5 - $2 : 1/0) with vectors nohead lc rgb '#aaaaaa' notitle, \
       $city using 1:($3 == 1 ? $2 : 1/0) with points pt 7 ps psz lc rgb '#1f77b4' title '1 thread', \
       $city using 1:($3 == 2 ? $2 : 1/0) with points pt 9 ps psz * 1.15 lc rgb '#d62728' title '2 threads', \
       $city_labels using 1:2:3 with labels left font ',10' notitle
  set title 'random towns (3)'
  plot $rnd_front using 1:2 with steps lw 2 lc rgb '#2ca02c' title 'Pareto front', \
       $rnd_labels using 1:2:($4 - $1):($6 > 0 ? $5 - $2 : 1/0) with vectors nohead lc rgb '#aaaaaa' notitle, \
       $rnd using 1:($3 == 1 ? $2 : 1/0) with points pt 7 ps psz lc rgb '#1f77b4' title '1 thread', \
       $rnd using 1:($3 == 2 ? $2 : 1/0) with points pt 9 ps psz * 1.15 lc rgb '#d62728' title '2 threads', \
       $rnd_labels using 1:2:3 with labels left font ',10' notitle
  unset multiplot
  set output
}
