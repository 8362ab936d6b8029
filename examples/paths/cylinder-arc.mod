MODULE CylinderArc
  ! 27 points written by forcelearn; poses in mm and unit quaternions (q1 scalar)
  PERS tooldata tRoller := [TRUE, [[0,0,150],[1,0,0,0]],
    [0.9,[0,0,60],[1,0,0,0],0,0,0]];
  TASK PERS wobjdata wCylinder := [FALSE, TRUE, "", [[900,0,0],[0.707107,0,0,0.707107]],
    [[0,0,0],[1,0,0,0]]];
  CONST robtarget p10 := [[0,63.3927,135.9462],[0.153046,0.690346,-0.690346,0.153046],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p20 := [[0,58.795,137.9969],[0.14144,0.692817,-0.692817,0.14144],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p30 := [[0,54.131,139.8922],[0.129793,0.695093,-0.695093,0.129793],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p40 := [[0,49.4061,141.6299],[0.118111,0.697173,-0.697173,0.118111],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p50 := [[0,44.6255,143.2081],[0.106394,0.699057,-0.699057,0.106394],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p60 := [[0,39.7946,144.625],[0.094648,0.700744,-0.700744,0.094648],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p70 := [[0,34.9189,145.879],[0.082876,0.702233,-0.702233,0.082876],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p80 := [[0,30.0039,146.9686],[0.07108,0.703525,-0.703525,0.07108],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p90 := [[0,25.055,147.8927],[0.059264,0.704619,-0.704619,0.059264],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p100 := [[0,20.078,148.6502],[0.047431,0.705514,-0.705514,0.047431],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p110 := [[0,15.0783,149.2402],[0.035585,0.706211,-0.706211,0.035585],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p120 := [[0,10.0616,149.6622],[0.023729,0.706709,-0.706709,0.023729],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p130 := [[0,5.0337,149.9155],[0.011866,0.707007,-0.707007,0.011866],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p140 := [[0,0,150],[0,0.707107,-0.707107,0],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p150 := [[0,-5.0337,149.9155],[0.011866,-0.707007,0.707007,0.011866],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p160 := [[0,-10.0616,149.6622],[0.023729,-0.706709,0.706709,0.023729],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p170 := [[0,-15.0783,149.2402],[0.035585,-0.706211,0.706211,0.035585],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p180 := [[0,-20.078,148.6502],[0.047431,-0.705514,0.705514,0.047431],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p190 := [[0,-25.055,147.8927],[0.059264,-0.704619,0.704619,0.059264],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p200 := [[0,-30.0039,146.9686],[0.07108,-0.703525,0.703525,0.07108],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p210 := [[0,-34.9189,145.879],[0.082876,-0.702233,0.702233,0.082876],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p220 := [[0,-39.7946,144.625],[0.094648,-0.700744,0.700744,0.094648],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p230 := [[0,-44.6255,143.2081],[0.106394,-0.699057,0.699057,0.106394],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p240 := [[0,-49.4061,141.6299],[0.118111,-0.697173,0.697173,0.118111],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p250 := [[0,-54.131,139.8922],[0.129793,-0.695093,0.695093,0.129793],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p260 := [[0,-58.795,137.9969],[0.14144,-0.692817,0.692817,0.14144],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];
  CONST robtarget p270 := [[0,-63.3927,135.9462],[0.153046,-0.690346,0.690346,0.153046],
    [0,0,0,0],[9E+09,9E+09,9E+09,9E+09,9E+09,9E+09]];

  PROC main()
    MoveL p10, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p20, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p30, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p40, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p50, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p60, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p70, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p80, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p90, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p100, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p110, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p120, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p130, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p140, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p150, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p160, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p170, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p180, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p190, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p200, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p210, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p220, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p230, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p240, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p250, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p260, v50, z1, tRoller \WObj:=wCylinder;
    MoveL p270, v50, z1, tRoller \WObj:=wCylinder;
  ENDPROC
ENDMODULE
