MODULE FCPolish
  ! An FC Pressure program (RobotWare Force Control): the path is its robtargets.
  PERS tooldata tPolish := [TRUE,[[0,0,200],[1,0,0,0]],[2.1,[0,0,90],[1,0,0,0],0,0,0]];
  PERS loaddata lPolish := [2.1,[0,0,90],[1,0,0,0],0,0,0];
  TASK PERS wobjdata wPart := [FALSE,TRUE,"",[[800,0,300],[1,0,0,0]],[[0,0,0],[1,0,0,0]]];
  CONST robtarget p10 := [[0,0,5],[0,1,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p20 := [[100,0,0],[0,1,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p30 := [[150,50,0],[0,1,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];
  CONST robtarget p40 := [[200,0,0],[0,1,0,0],[0,0,0,0],[9E9,9E9,9E9,9E9,9E9,9E9]];

  PROC polish()
    FCLoadId;
    FCCalib lPolish;
    FCPress1LStart p10, v10 \Fz:=150, 15 \ForceChange:=100 \PosSupvDist:=125, z5, tPolish \WObj:=wPart;
    FCPressL p20, v50, 150, z5, tPolish \WObj:=wPart;
    FCPressC p30, p40, v50, 150, z5, tPolish \WObj:=wPart;
    FCPressEnd Offs(p40,0,0,50), v100, tPolish \WObj:=wPart;
  ENDPROC
ENDMODULE
